#version 430
// Ray-traced primary visibility: the camera model's rays (common/camera.glsl) through the BVH,
// writing what the G-buffer resolve needs: the triangle ID, and in position the sub-ray index
// (x, as uint bits: the resolve re-casts that sub-ray) and the hit distance (w, its fallback when
// the triangle is seen edge-on); with SAMPLED, each pixel's weight in the frame's colour.
// The resolve (gbuffer/resolve.comp with PRIMARY_RAYS) then fills every channel.
//
// PRIMARY_MODE 0: one ray per sample, sub-ray `subsample` of CAMERA_SUBSAMPLES (1x: the central
//   ray; SSAA: the frame round's sub-ray, weight 1 / CAMERA_SUBSAMPLES).
// PRIMARY_MODE 1 (MSAA, trace): all CAMERA_SUBSAMPLES sub-rays; the distinct triangles they hit
//   (the background counts as one) with their coverage masks go to msaa_hits, most covered first,
//   at most MSAA_SLOTS; the largest count of any pixel to msaa_count (one atomic per workgroup).
// PRIMARY_MODE 2 (MSAA, select): slot `msaa_slot` of each pixel's list becomes its visibility,
//   shaded at the sub-ray of its mask nearest the mask's mean_offset, weighted by its coverage.
#ifndef PRIMARY_MODE
#define PRIMARY_MODE 0
#endif
#ifndef SAMPLED
#define SAMPLED 0
#endif
#ifndef MSAA_SLOTS
#define MSAA_SLOTS 1
#endif
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "../layout.glsl"
#include "../accel/bvh.glsl"
#include "../common/camera.glsl"

layout(rgba32f, binding = GB_IMAGE_POSITION) uniform writeonly image2DArray img_position;
layout(r32ui, binding = GB_IMAGE_TRIANGLE) uniform writeonly uimage2DArray img_triangle;
#if SAMPLED
layout(r32f, binding = IMAGE_SAMPLE_WEIGHT) uniform writeonly image2DArray img_weight;
#endif
#if PRIMARY_MODE != 0
// Per pixel MSAA_SLOTS entries, slot-major (HIT below): (triangle, coverage mask, representative sub-ray | count << 8 |
// covered sub-rays << 16 (entry 0 only), hit distance bits).
layout(std430, binding = SSBO_MSAA_HITS) buffer MsaaHits { uvec4 msaa_hits[]; };
layout(std430, binding = SSBO_MSAA_COUNT) buffer MsaaCount { uint msaa_count; };
#endif
#if PRIMARY_MODE == 1
// The workgroup's largest count: one global atomic per workgroup, not one per pixel (every
// invocation of the frame contending for one address was a fixed cost of each MSAA frame).
shared uint group_count;
#endif
uniform int subsample;  // PRIMARY_MODE 0
uniform int msaa_slot;  // PRIMARY_MODE 2

// Closest hit of one camera ray; false: the sample makes no ray.
bool cast_primary(int eye, vec3 o, vec3 d, out Hit h) {
    Ray r = Ray(o, 0.0, d, 3.0e38);
    float along = max(camera_depth_per_distance(eye, d), 1e-30);
    if (eye_depth.y > 0.0) r.tmax = eye_depth.y / along;  // a finite far plane clips as the rasterizer does
    r.tmin = eye_depth.x / along;
    trace_closest(r, h);
    return true;
}

void store(ivec3 p, uint tri, uint sub, float t, float weight) {
    imageStore(img_triangle, p, uvec4(tri));
    imageStore(img_position, p, vec4(uintBitsToFloat(sub), 0.0, 0.0, t));
#if SAMPLED
    imageStore(img_weight, p, vec4(weight));
#endif
}

#if PRIMARY_MODE != 0
// Slot-major entries (slot k of every pixel, then slot k + 1): neighbouring invocations write and
// read neighbouring entries.
#define HIT(k) msaa_hits[index + uint(k) * pixels]
#endif
#if PRIMARY_MODE == 1
// All sub-rays of the sample at pixel p; its distinct triangles to msaa_hits; their number.
uint msaa_trace(ivec3 p, ivec2 size, uint index, uint pixels) {
    vec2 pixel_center = vec2(p.xy) + 0.5;
    bool sample_here = camera_footprint(p.z, pixel_center, vec2(size)) > 0.0;
    if (!sample_here) {  // no sample at this pixel (foveated): an empty list, filled for display
        HIT(0) = uvec4(BVH_MISS, 0u, 0u, 0u);
        return 0u;
    }
    uint tris[CAMERA_SUBSAMPLES];
    float ts[CAMERA_SUBSAMPLES];
    for (int i = 0; i < CAMERA_SUBSAMPLES; i++) {
        vec3 o, d;
        Hit h;
        h.prim = BVH_MISS;
        h.t = 0.0;
        if (camera_subray(p.z, pixel_center, vec2(size), uint(i), o, d)) cast_primary(p.z, o, d, h);
        tris[i] = h.prim;
        ts[i] = h.t;
    }
    // Distinct triangles and their coverage masks (sub-ray i is bit i).
    uint ids[MSAA_SLOTS], masks[MSAA_SLOTS];
    int n = 0;
    for (int i = 0; i < CAMERA_SUBSAMPLES; i++) {
        int k = 0;
        while (k < n && ids[k] != tris[i]) k++;
        if (k == n) {
            if (n == MSAA_SLOTS) continue;  // more triangles than slots: this sub-ray is dropped
            ids[n] = tris[i];
            masks[n] = 0u;
            n++;
        }
        masks[k] |= 1u << uint(i);
    }
    uint covered = 0u;
    for (int k = 0; k < n; k++) covered += uint(bitCount(masks[k]));
    for (int k = 0; k < n; k++) {
        // Stored most covered first (slot 0 is the pixel's main surface, the G-buffer the frame
        // keeps): the slot is the entry's rank, ties in order of first sub-ray.
        int rank = 0;
        for (int j = 0; j < n; j++)
            rank += int(bitCount(masks[j]) > bitCount(masks[k]) || (bitCount(masks[j]) == bitCount(masks[k]) && j < k));
        // The sub-ray nearest the mean of the mask's footprint offsets: shaded for all of them.
        vec2 mean_offset = vec2(0.0);
        for (int i = 0; i < CAMERA_SUBSAMPLES; i++)
            if ((masks[k] & (1u << uint(i))) != 0u) mean_offset += camera_subpixel(uint(i));
        mean_offset /= float(bitCount(masks[k]));
        int best = 0;
        float best_d = 1e30;
        for (int i = 0; i < CAMERA_SUBSAMPLES; i++) {
            vec2 e = camera_subpixel(uint(i)) - mean_offset;
            if ((masks[k] & (1u << uint(i))) != 0u && dot(e, e) < best_d) { best = i; best_d = dot(e, e); }
        }
        uint meta = uint(best) | (rank == 0 ? (uint(n) << 8) | (covered << 16) : 0u);
        HIT(rank) = uvec4(ids[k], masks[k], meta, floatBitsToUint(ts[best]));
    }
    return uint(n);
}
#endif

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec3 extent = imageSize(img_triangle);
    ivec2 size = extent.xy;
    bool inside = all(lessThan(p.xy, size));
#if PRIMARY_MODE != 0
    uint pixels = uint(extent.x * extent.y * extent.z), index = uint((p.z * size.y + p.y) * size.x + p.x);
#endif
#if PRIMARY_MODE == 1
    if (gl_LocalInvocationIndex == 0u) group_count = 0u;
    barrier();
    if (inside) atomicMax(group_count, msaa_trace(p, size, index, pixels));
    barrier();
    if (gl_LocalInvocationIndex == 0u && group_count > 0u) atomicMax(msaa_count, group_count);
#else
    if (!inside) return;
    vec2 pixel = vec2(p.xy) + 0.5;
#if PRIMARY_MODE == 0
    vec3 o, d;
    Hit h;
    h.prim = BVH_MISS;
    h.t = 0.0;
    bool sample_here = camera_footprint(p.z, pixel, vec2(size)) > 0.0;
    if (camera_subray(p.z, pixel, vec2(size), uint(subsample), o, d)) cast_primary(p.z, o, d, h);
    // A pixel without a sample (foveated) weighs nothing: the resolve fills it for display.
    store(p, h.prim, uint(subsample), h.t, sample_here ? 1.0 / float(CAMERA_SUBSAMPLES) : 0.0);
#else
    uvec4 head = HIT(0);
    uint n = (head.z >> 8) & 255u, covered = head.z >> 16;
    if (uint(msaa_slot) < n) {
        uvec4 e = HIT(msaa_slot);
        store(p, e.x, e.z & 255u, uintBitsToFloat(e.w), float(bitCount(e.y)) / float(max(covered, 1u)));
    } else {
        store(p, BVH_MISS, 0u, 0.0, 0.0);  // nothing in this slot: shaded as background, weighs nothing
    }
#endif
#endif
}
