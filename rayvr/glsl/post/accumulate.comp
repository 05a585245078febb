#version 430
// Accumulate: the running mean of the frame's samples per pixel (rayvr/frame/passes/accumulate.py), and
// the first two moments of the demodulated luminance, whose spread is the variance the denoiser's
// luminance edge-stop uses (SVGF). While the view is still the history is this pixel's own
// (reproject 0: read and written in place). With temporal reprojection a moved camera finds the
// history where the surface point was in the previous frame: the point is projected through the
// previous pinhole camera, and the history is dropped (disocclusion) when the depth stored there
// disagrees or it was another material.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/gbuffer.glsl"
#include "demodulate.glsl"

layout(rgba16f, binding = IMAGE_HDR) uniform readonly image2DArray hdr_in;  // this frame's sample
layout(rgba32f, binding = IMAGE_ACCUM_IN) uniform readonly image2DArray history_in;  // rgb mean, a samples
layout(rgba32f, binding = IMAGE_ACCUM_MOMENTS_IN) uniform readonly image2DArray moments_in;
layout(rgba32f, binding = IMAGE_ACCUM_OUT) uniform writeonly image2DArray accum_out;
// x mean luminance (demodulated), y mean of its square, z view depth, w material index + 1 (0: background)
layout(rgba32f, binding = IMAGE_ACCUM_MOMENTS_OUT) uniform writeonly image2DArray moments_out;
#if ACCUM_HISTORY
layout(rgba32f, binding = IMAGE_ACCUM_HISTORY_OUT) uniform writeonly image2DArray history_out;
layout(rgba32f, binding = IMAGE_ACCUM_HISTORY_MOMENTS_OUT) uniform writeonly image2DArray history_moments_out;
#endif

uniform int reset;        // 1: this frame starts over
uniform int reproject;    // 1: find the history through the previous camera (temporal, camera moved)
uniform float history_cap;  // a history counts for at most this many samples
uniform vec3 prev_eye_position[2];
uniform mat3 prev_eye_rotation[2];
uniform vec4 prev_eye_tangents[2];

#define DISOCCLUSION_DEPTH 0.02  // relative view-depth difference beyond which history is another surface

// Where scene-local point `x` was seen by the previous camera of `eye`: its pixel (false when
// outside that image or behind the eye) and view depth there.
bool previous_pixel(int eye, vec3 x, ivec2 size, out ivec2 q, out float depth) {
    vec3 local = transpose(prev_eye_rotation[eye]) * (x - prev_eye_position[eye]);
    depth = -local.z;
    if (depth <= 0.0) return false;
    vec4 t = prev_eye_tangents[eye];
    vec2 f = (local.xy / depth - t.xz) / (t.yw - t.xz);
    vec2 pix = floor(f * vec2(size));
    q = ivec2(pix);
    return all(greaterThanEqual(pix, vec2(0.0))) && all(lessThan(pix, vec2(size)));
}

void store(ivec3 p, vec4 accum, vec4 moments) {
    imageStore(accum_out, p, accum);
    imageStore(moments_out, p, moments);
#if ACCUM_HISTORY
    imageStore(history_out, p, accum);
    imageStore(history_moments_out, p, moments);
#endif
}

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 size = imageSize(accum_out).xy;
    if (any(greaterThanEqual(p.xy, size))) return;
    vec3 c = finite_or_zero(imageLoad(hdr_in, p).rgb);
    uvec2 m = texelFetch(gb_material, p, 0).xy;
    if (m.y == BACKGROUND_EFFECT) {  // the background is no sample: it is what it is
        store(p, vec4(c, 1.0), vec4(0.0));
        return;
    }
    vec4 pos = texelFetch(gb_position, p, 0);
    float l = luminance(c / demodulation_albedo(texelFetch(gb_albedo, p, 0).rgb));
    ivec3 q = p;
    bool valid = reset == 0;
    if (valid && reproject != 0) {
        float depth;
        valid = previous_pixel(p.z, pos.xyz, size, q.xy, depth);
        if (valid) {
            vec4 hm = imageLoad(moments_in, q);
            valid = hm.w == float(m.x + 1u) && abs(hm.z - depth) <= DISOCCLUSION_DEPTH * depth;
        }
    }
    vec4 h = valid ? imageLoad(history_in, q) : vec4(0.0);
    vec4 hm = valid ? imageLoad(moments_in, q) : vec4(0.0);
    float n = min(h.a, history_cap) + 1.0;
    float a = 1.0 / n;  // exact running mean while n < cap, exponential moving average after
    store(p, vec4(mix(h.rgb, c, a), n), vec4(mix(hm.xy, vec2(l, l * l), a), pos.w, float(m.x + 1u)));
}
