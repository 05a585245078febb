// What ray-cast primary visibility writes (rt/primary.comp, and rt/tile_samples.comp from the tile
// lists): per pixel the triangle ID, and in position the sub-ray index (x, as uint bits: the G-buffer
// resolve re-casts that sub-ray) and the hit distance (w); with SAMPLED, the pixel's weight in the
// frame's colour; with MSAA_OUT, the MSAA trace's per-pixel lists of distinct triangles and their count.
#ifndef RAYVR_RT_PRIMARY_OUT_GLSL
#define RAYVR_RT_PRIMARY_OUT_GLSL
#include "../layout.glsl"

layout(rgba32f, binding = GB_IMAGE_POSITION) uniform writeonly image2DArray img_position;
layout(r32ui, binding = GB_IMAGE_TRIANGLE) uniform writeonly uimage2DArray img_triangle;
#if SAMPLED
layout(r32f, binding = IMAGE_SAMPLE_WEIGHT) uniform writeonly image2DArray img_weight;
#endif

void store(ivec3 p, uint tri, uint sub, float t, float weight) {
    imageStore(img_triangle, p, uvec4(tri));
    imageStore(img_position, p, vec4(uintBitsToFloat(sub), 0.0, 0.0, t));
#if SAMPLED
    imageStore(img_weight, p, vec4(weight));
#endif
}

// SHARE_CHANNELS (one sub-ray per sample, frame/passes/primary_rays.py shares_channels): share_mode 1
// casts the green channel into channel_probe (its triangle and distance: the frame's first round);
// 2, in the red and blue rounds, leaves the pixels whose ray hits green's triangle to green (weight
// ROUND_SKIPPED, no visibility written: common/round_skip.glsl) and marks them in channel_match (bit =
// channel), whose colour sample_accumulate then takes from green's round; 3, green's round, writes the
// probe's hits as its visibility (rt/primary.comp) instead of casting the same rays again.
#ifndef SHARE_CHANNELS
#define SHARE_CHANNELS 0
#endif
#if SHARE_CHANNELS
layout(rg32ui, binding = IMAGE_CHANNEL_PROBE) uniform uimage2DArray img_probe;
layout(r32ui, binding = IMAGE_CHANNEL_MATCH) uniform uimage2DArray img_match;
uniform int share_mode;
#endif

// What a cast of one sub-ray per sample (sub-ray `sub` of the pixel's footprint, weight 1 / sub-rays)
// writes for pixel p (inside the image) whose ray hit triangle `tri` at t, per the share mode.
void store_cast(ivec3 p, bool sample_here, uint tri, float t, uint sub) {
#if SHARE_CHANNELS
    if (share_mode == 1) {
        imageStore(img_probe, p, uvec4(tri, floatBitsToUint(t), 0u, 0u));
        return;
    }
    if (share_mode == 2) {
        // the same triangle (or both background) as green's ray: green's shading serves this channel
        bool same = sample_here && imageLoad(img_probe, p).x == tri;
        uint bits = camera_channel == 0 ? 0u : imageLoad(img_match, p).x;   // red's round is the first
        imageStore(img_match, p, uvec4(bits | (same ? 1u << uint(camera_channel) : 0u)));
        if (same) {
            imageStore(img_weight, p, vec4(ROUND_SKIPPED));
            return;
        }
    }
#endif
    // A pixel without a sample (foveated) weighs nothing: the resolve fills it for display.
    store(p, tri, sub, t, sample_here ? 1.0 / float(CAMERA_SUBSAMPLES) : 0.0);
}

#ifndef MSAA_OUT
#define MSAA_OUT 0
#endif
#if MSAA_OUT
// Per pixel MSAA_SLOTS entries, slot-major (HIT below): (triangle, coverage mask, representative sub-ray | count << 8 |
// covered sub-rays << 16 (entry 0 only), hit distance bits).
layout(std430, binding = SSBO_MSAA_HITS) buffer MsaaHits { uvec4 msaa_hits[]; };
layout(std430, binding = SSBO_MSAA_COUNT) buffer MsaaCount { uint msaa_count; };
// Slot-major entries (slot k of every pixel, then slot k + 1): neighbouring invocations write and
// read neighbouring entries. `index`: the pixel's, `pixels`: of the frame.
#define HIT(k) msaa_hits[index + uint(k) * pixels]
#endif
#endif
