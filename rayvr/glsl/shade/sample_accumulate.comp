#version 430
// One round of a sampled frame (frame/passes/sample_accumulate.py): adds each pixel's colour of this
// round, times its weight (primary_rays: 1/N per SSAA sub-ray, coverage per MSAA triangle, 0 where
// the camera has no sample, negative where an MSAA round skips the pixel), to the frame's sum; a
// colour-channel round adds only its channel. Weights <= 0 leave the sum as it is (exact: they
// add zero), so an MSAA round's empty pixels cost a 4-byte read.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/round_skip.glsl"  // round_pixel (ROUND_TILES; it reads the weights itself: ROUND_SKIP 0)

layout(rgba16f, binding = IMAGE_HDR) uniform readonly image2DArray hdr_in;
layout(r32f, binding = IMAGE_SAMPLE_WEIGHT) uniform readonly image2DArray weight_in;
layout(rgba32f, binding = IMAGE_SAMPLE_SUM) uniform image2DArray sum;
#ifndef SHARE_CHANNELS
#define SHARE_CHANNELS 0
#endif
#if SHARE_CHANNELS
// Shared channel shading (frame/passes/primary_rays.py shares_channels): the colour channel sets are
// sub-rays of every round's surface; each channel takes its own weight of it (rgb), a green's.
layout(rgba32f, binding = IMAGE_CHANNEL_WEIGHT) uniform readonly image2DArray channel_weight;
#endif
uniform int first;    // the frame's first round: start from zero
uniform int channel;  // -1: all three; else this colour channel only

void main() {
    ivec3 p = round_pixel();  // (an MSAA round but the frame's first: over its listed tiles)
    if (any(greaterThanEqual(p.xy, imageSize(sum).xy))) return;
    float w = imageLoad(weight_in, p).x;
    if (!(w > 0.0)) {  // adds nothing (no sample here, or skipped: common/round_skip.glsl): the sum stays
        if (first != 0) imageStore(sum, p, vec4(0.0));
        return;
    }
    vec4 acc = first != 0 ? vec4(0.0) : imageLoad(sum, p);
    vec3 c = imageLoad(hdr_in, p).rgb;
#if SHARE_CHANNELS
    acc += imageLoad(channel_weight, p) * vec4(c, 1.0);
#else
    if (channel < 0) acc.rgb += w * c;
    else acc[channel] += w * c[channel];
    if (channel <= 0) acc.a += w;  // the weight of one channel set: 0 where no sample was made
#endif
    imageStore(sum, p, acc);
}
