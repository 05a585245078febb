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
