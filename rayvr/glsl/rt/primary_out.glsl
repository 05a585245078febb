// What ray-cast primary visibility writes (rt/primary.comp, and rt/tile_samples.comp from the tile
// lists): per pixel the triangle ID, and in position the sub-ray index (x, as uint bits: the G-buffer
// resolve re-casts that sub-ray) and the hit distance (w); with SAMPLED, the pixel's weight in the
// frame's colour; with MSAA_OUT, the MSAA trace's per-pixel lists of distinct triangles and their count.
#ifndef RAYVR_RT_PRIMARY_OUT_GLSL
#define RAYVR_RT_PRIMARY_OUT_GLSL
#include "../layout.glsl"
#include "sub_mask.glsl"

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

// What a cast of one sub-ray per sample (sub-ray `sub` of the pixel's footprint, weight 1 / sub-rays)
// writes for pixel p (inside the image) whose ray hit triangle `tri` at t.
void store_cast(ivec3 p, bool sample_here, uint tri, float t, uint sub) {
    // A pixel without a sample (foveated) weighs nothing: the resolve fills it for display.
    store(p, tri, sub, t, sample_here ? 1.0 / float(CAMERA_SUBSAMPLES) : 0.0);
}

#ifndef MSAA_OUT
#define MSAA_OUT 0
#endif
#if MSAA_OUT
// Per pixel MSAA_SLOTS entries, slot-major (HIT below): (triangle, coverage (msaa_coverage of its
// mask), representative sub-ray | count << 8 | covered sub-rays << 16 (entry 0 only), hit distance bits).
layout(std430, binding = SSBO_MSAA_HITS) buffer MsaaHits { uvec4 msaa_hits[]; };
layout(std430, binding = SSBO_MSAA_COUNT) buffer MsaaCount { uint msaa_count; };
// Slot-major entries (slot k of every pixel, then slot k + 1): neighbouring invocations write and
// read neighbouring entries. `index`: the pixel's, `pixels`: of the frame.
#define HIT(k) msaa_hits[index + uint(k) * pixels]

// Each sub-ray's footprint offset (camera_subray_offset), filled once a workgroup by the includer.
shared vec2 sub_offset[CAMERA_SUBRAYS];

// The sub-ray of coverage mask `mask` nearest the mean of its sub-rays' footprint offsets, at which
// the entry is shaded for all of them (the mask's bits in increasing order: the first of equally
// near ones; passes/primary_rays.py msaa_lists is the numpy twin).
uint msaa_representative(SubMask mask) {
    vec2 mean_offset = vec2(0.0);
    for (SubMask m = mask; !mask_empty(m); m = mask_drop_lsb(m)) mean_offset += sub_offset[mask_lsb(m)];
    mean_offset /= float(mask_count(mask));
    uint best = 0u;
    float best_d = 1e30;
    for (SubMask m = mask; !mask_empty(m); m = mask_drop_lsb(m)) {
        uint i = mask_lsb(m);
        vec2 e = sub_offset[i] - mean_offset;
        if (dot(e, e) < best_d) { best = i; best_d = dot(e, e); }
    }
    return best;
}

// The covered count a kept entry of coverage mask `mask` adds to its pixel's (the meta's high bits):
// its sub-rays, or with CHANNEL_SAMPLES 3 each colour channel set's, 5 bits a set (set c at bit 5c).
uint msaa_coverage(SubMask mask) {
#if CHANNEL_SAMPLES > 1
    uint covered = 0u;
    for (uint b = 0u; b < uint(CHANNEL_SAMPLES); ++b) {
        uint first = b * uint(CAMERA_SUBSAMPLES);
        uint in_set = mask_count_below(mask, first + uint(CAMERA_SUBSAMPLES)) - mask_count_below(mask, first);
        covered += in_set << (5u * uint(camera_subray_channel(first)));
    }
    return covered;
#else
    return mask_count(mask);
#endif
}

#if CHANNEL_SAMPLES > 1
// Each colour channel's weight of the entry (rgb; a: green's, the sample sum's weight), which
// sample_accumulate applies to its own channel.
layout(rgba32f, binding = IMAGE_CHANNEL_WEIGHT) uniform writeonly image2DArray img_channel_weight;
#endif

// The select's weight of pixel p's entry of coverage `mine` (msaa_coverage of its mask) among its
// `covered` (those summed): its share of the pixel's sub-rays; with CHANNEL_SAMPLES 3 each channel
// set's share, stored in channel_weight, and the largest of them (the round skips a pixel only where
// all are 0). A set none of whose sub-rays hit a kept triangle (a pixel with more than MSAA_SLOTS)
// takes the entry's share of all three sets: its weights still sum to one.
uint coverage_sum(uint c) { return (c & 31u) + ((c >> 5) & 31u) + ((c >> 10) & 31u); }
float msaa_weight(ivec3 p, uint mine, uint covered) {
#if CHANNEL_SAMPLES > 1
    vec3 w;
    float whole = float(coverage_sum(mine)) / float(max(coverage_sum(covered), 1u));
    for (int c = 0; c < 3; ++c) {
        uint set_covered = (covered >> (5 * c)) & 31u;
        w[c] = set_covered > 0u ? float((mine >> (5 * c)) & 31u) / float(set_covered) : whole;
    }
    imageStore(img_channel_weight, p, vec4(w, w.g));
    return max(max(w.r, w.g), w.b);
#else
    return float(mine) / float(max(covered, 1u));
#endif
}
#endif
#endif
