#version 430
// Ray-traced primary visibility: the camera model's rays (common/camera.glsl) through the BVH,
// writing what the G-buffer resolve needs: the triangle ID, and in position the sub-ray index
// (x, as uint bits: the resolve re-casts that sub-ray) and the hit distance (w, its fallback when
// the triangle is seen edge-on); with SAMPLED, each pixel's weight in the frame's colour.
// The resolve (gbuffer/resolve.comp with PRIMARY_RAYS) then fills every channel.
//
// PRIMARY_MODE 0: one ray per sample, sub-ray `subsample` of CAMERA_SUBSAMPLES (1x: the central
//   ray; SSAA: the frame round's sub-ray, weight 1 / CAMERA_SUBSAMPLES).
// PRIMARY_MODE 1 (MSAA, trace): all CAMERA_SUBRAYS sub-rays, one invocation each (a workgroup
//   is a block of MSAA_BLOCK_W x MSAA_BLOCK_H pixels times their sub-rays); then the pixel's sub-rays
//   merge their hits from shared memory, each invocation its own (msaa_merge): the distinct
//   triangles, or smooth surfaces (rt/same_surface.glsl; the background counts as one), with their
//   coverage masks go to msaa_hits, most covered first, at most MSAA_SLOTS; the largest count of any pixel to msaa_count (at most one
//   atomic per workgroup). frame/passes/primary_rays.py msaa_lists is the numpy twin of the merge.
//   (On the GPU the merge by one invocation per pixel was 30 % of the 16x trace: room 8.25 -> 5.76
//   ms with every lane merging; the ~80 ms frames of an
//   earlier version came from msaa_count, see primary_rays.py.)
// PRIMARY_MODE 2 (MSAA, select): slot msaa_count - 1 - `msaa_round` of each pixel's list (slot 0
//   for msaa_round -1) becomes its visibility, shaded at the sub-ray of its mask nearest the mask's
//   mean_offset, weighted by its coverage (with CHANNEL_SAMPLES 3, whose sub-rays are all three
//   colour channel sets', each channel by its set's: channel_weight, primary_out.glsl msaa_weight).
//   The slot comes from the GPU's count: the CPU records rounds before it knows the count. A pixel
//   with nothing in the round gets weight ROUND_SKIPPED
//   and keeps its visibility (common/round_skip.glsl): in a round past the count (slot < 0: slot
//   0, the last real one, made its G-buffer) and, with MSAA_SKIP_EMPTY, in an empty slot above 0
//   (slot 0 always writes every pixel: an empty list gets the background, weight 0).
#ifndef PRIMARY_MODE
#define PRIMARY_MODE 0
#endif
#ifndef SAMPLED
#define SAMPLED 0
#endif
#ifndef MSAA_SLOTS
#define MSAA_SLOTS 1
#endif
#ifndef MSAA_SKIP_EMPTY
#define MSAA_SKIP_EMPTY 0
#endif
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
#if PRIMARY_MODE == 1
layout(local_size_x = MSAA_GROUP) in;  // = MSAA_BLOCK_W * MSAA_BLOCK_H * CAMERA_SUBRAYS (a literal: GLSL 4.30)
#else
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#endif
#include "../accel/bvh.glsl"
#include "../common/camera.glsl"
#include "../common/round_skip.glsl"
#include "primary_ray.glsl"
#include "same_surface.glsl"
#define MSAA_OUT (PRIMARY_MODE != 0)
#include "primary_out.glsl"
#if PRIMARY_MODE == 1
// The workgroup's largest count: at most one global atomic per workgroup, not one per pixel.
shared uint group_count;
shared uint sub_tri[MSAA_GROUP];   // each sub-ray's triangle (BVH_MISS: background), distance and
shared float sub_t[MSAA_GROUP];    //   surface (rt/same_surface.glsl), pixel-major: the block's pixel j
shared uint sub_surface[MSAA_GROUP];  // has entries j * N .. j * N + N - 1
#endif
uniform int subsample;  // PRIMARY_MODE 0
uniform int msaa_round;  // PRIMARY_MODE 2
#if PRIMARY_MODE == 2 && ROUND_TILES
shared uint tile_live;  // some pixel of the tile is not skipped (common/round_skip.glsl's list)
#endif

// TILE_LIST_OVERFLOW 1 (with tile lists, frame/passes/primary_rays.py): cast only the tiles whose
// list overflowed, per ray from their entries (rt/tile_samples.comp casts the others from their lists).
#ifndef TILE_LIST_OVERFLOW
#define TILE_LIST_OVERFLOW 0
#endif
#if TILE_LIST_OVERFLOW
layout(std430, binding = TILE_TRIS_BINDING) readonly restrict buffer TileTris { uvec2 tile_tris[]; };
#endif

// Closest hit h of the camera ray (o, d) of pixel p where `valid` (h as it was elsewhere): from the
// BVH root, or with tile culling (TILE_ENTRIES_BINDING, frame/passes/primary_rays.py) from the entry
// list of the pixel's tile, which tile_cull.comp made for every sub-ray of the tile's pixels: the
// same hit, less work.
void cast_primary(ivec3 p, ivec2 size, bool valid, vec3 o, vec3 d, inout Hit h) {
    Ray r = primary_ray(p.z, o, d);
#if defined(TILE_ENTRIES_BINDING)
    if (valid) trace_closest_in_tile(r, primary_tile(p, size), h);
#else
    if (valid) trace_closest(r, h);
#endif
}
#if PRIMARY_MODE == 1
shared SubMask sub_mask[MSAA_GROUP];                              // each sub-ray's links, then its entry's coverage mask
shared uint pixel_first[MSAA_BLOCK_W * MSAA_BLOCK_H * MASK_WORDS]; // the first sub-ray on each distinct triangle
shared uint pixel_covered[MSAA_BLOCK_W * MSAA_BLOCK_H];            // sub-rays on the kept triangles
shared uint pixel_mixed[MSAA_BLOCK_W * MSAA_BLOCK_H];              // 1: the pixel's sub-rays make more than one entry

// The sample at pixel p, block pixel j, whose sub-rays' hits are sub_tri/sub_t[base ..]: its
// entries to msaa_hits; their number. Every invocation of the group calls it, each for its own
// sub-ray `sub` (all lanes work: one lane per pixel merging alone left 15 of 16 idle at 16x): the
// first sub-ray of an entry writes it, with the triangle its representative sub-ray hit.
uint msaa_merge(ivec3 p, ivec2 size, uint index, uint pixels, uint base, uint sub, uint j, bool inside) {
    // The coverage mask of this sub-ray's entry (sub-ray i is bit i): the sub-rays linked to it
    // (rt/same_surface.glsl: on one triangle, or with MSAA_MERGE_SURFACES one surface at one
    // depth), directly or through others; entries are ranked by coverage (ties in order of first
    // sub-ray) and only the MSAA_SLOTS most covered are kept (the sub-rays on the others are
    // dropped: the kept share the pixel among themselves).
    uint tri = sub_tri[base + sub], surface = sub_surface[base + sub];
    float t = sub_t[base + sub];
    if (sub == 0u) {
        for (uint w = 0u; w < MASK_WORDS; w++) pixel_first[MASK_WORDS * j + w] = 0u;
        pixel_covered[j] = 0u;
    }
    if (!same_surface(sub_tri[base], sub_surface[base], sub_t[base], tri, surface, t))
        pixel_mixed[j] = 1u;  // (main zeroed it before the trace's barrier)
    barrier();
    // Most pixels' sub-rays all link to the first: their mask is every sub-ray's, with no walk over
    // the pixel's sub-rays (O(N) a lane: at 48 sub-rays a large share of the merge).
    SubMask mask = MASK_ALL;
    if (pixel_mixed[j] != 0u) {  // the sub-rays linked to this one directly
        mask = MASK_NONE;
        for (uint k = 0u; k < uint(CAMERA_SUBRAYS); k++)
            if (same_surface(sub_tri[base + k], sub_surface[base + k], sub_t[base + k], tri, surface, t))
                mask |= MASK_BIT(k);
        sub_mask[base + sub] = mask;
    }
    barrier();
    if (pixel_mixed[j] != 0u) {  // grown by its members' links until it holds its whole entry
        for (SubMask grown = mask;; mask = grown) {
            for (SubMask m = mask; !mask_empty(m); m = mask_drop_lsb(m)) grown |= sub_mask[base + mask_lsb(m)];
            if (mask_same(grown, mask)) break;
        }
    }
    barrier();  // every lane has read the links before the masks replace them
    bool first = mask_lsb(mask) == sub;
    if (first) atomicOr(pixel_first[MASK_WORDS * j + sub / 32u], 1u << (sub % 32u));
    sub_mask[base + sub] = mask;
    barrier();
    SubMask firsts = MASK_OF_WORDS(pixel_first, MASK_WORDS * j);
    // The entry's rank among all the pixel's entries: its slot where it is kept.
    uint pop = mask_count(mask), rank = 0u;
    if (first && pixel_mixed[j] != 0u) {
        for (SubMask m = firsts; !mask_empty(m); m = mask_drop_lsb(m)) {
            uint k = mask_lsb(m), pk = mask_count(sub_mask[base + k]);
            rank += uint(pk > pop || (pk == pop && k < sub));
        }
    }
    bool kept = first && rank < uint(MSAA_SLOTS);
    uint coverage = kept ? msaa_coverage(mask) : 0u;
    if (kept) atomicAdd(pixel_covered[j], coverage);
    barrier();
    if (!inside) return 0u;
    if (!(camera_footprint(p.z, vec2(p.xy) + 0.5, vec2(size)) > 0.0)) {
        if (sub == 0u)
            HIT(0) = uvec4(BVH_MISS, 0u, 0u, 0u);  // no sample at this pixel (foveated): an empty list, filled for display
        return 0u;
    }
    uint n = min(mask_count(firsts), uint(MSAA_SLOTS));
    if (kept) {
        // Stored most covered first (slot 0 is the pixel's main surface, the G-buffer the frame keeps).
        uint best = msaa_representative(mask);
        uint meta = best | (rank == 0u ? (n << 8) | (pixel_covered[j] << 16) : 0u);
        HIT(rank) = uvec4(sub_tri[base + best], coverage, meta, floatBitsToUint(sub_t[base + best]));
    }
    return n;
}
#endif

void main() {
#if PRIMARY_MODE == 1
    // Invocation -> (pixel of the workgroup's block, sub-ray): a pixel's sub-rays are neighbouring
    // invocations (one warp traces a few neighbouring pixels' sub-rays: coherent rays).
    uint lid = gl_LocalInvocationIndex, sub = lid % uint(CAMERA_SUBRAYS), j = lid / uint(CAMERA_SUBRAYS);
    ivec3 p = ivec3(ivec2(gl_WorkGroupID.xy) * ivec2(MSAA_BLOCK_W, MSAA_BLOCK_H) +
                    ivec2(j % uint(MSAA_BLOCK_W), j / uint(MSAA_BLOCK_W)), gl_WorkGroupID.z);
#else
    ivec3 p = ivec3(gl_GlobalInvocationID);
#endif
    ivec3 extent = imageSize(img_triangle);
    ivec2 size = extent.xy;
    bool inside = all(lessThan(p.xy, size));
#if TILE_LIST_OVERFLOW && PRIMARY_MODE != 2
    // The group's pixels lie in one tile: the whole group leaves a tile with a list to tile_samples.comp.
    if (tile_tris[primary_tile(p, size) * uint(TILE_TRIS + 1)].x != TILE_OVERFLOW)
        return;
#endif
#if PRIMARY_MODE != 0
    uint pixels = uint(extent.x * extent.y * extent.z), index = uint((p.z * size.y + p.y) * size.x + p.x);
#endif
#if PRIMARY_MODE == 1
    if (lid == 0u) group_count = 0u;
    if (sub == 0u) pixel_mixed[j] = 0u;
    if (lid < uint(CAMERA_SUBRAYS)) sub_offset[lid] = camera_subray_offset(lid);
    vec3 o, d;
    Hit h;
    h.prim = BVH_MISS;
    h.t = 0.0;
    bool valid = inside && camera_subray(p.z, vec2(p.xy) + 0.5, vec2(size), sub, o, d);
    cast_primary(p, size, valid, o, d, h);
    sub_tri[lid] = h.prim;
    sub_t[lid] = h.t;
    sub_surface[lid] = surface_of(h.prim);
    barrier();
    uint n = msaa_merge(p, size, index, pixels, j * uint(CAMERA_SUBRAYS), sub, j, inside);
    if (inside && sub == 0u) atomicMax(group_count, n);
    barrier();
    // One round is the least a frame runs (primary_rays.py): only a count above 1 needs telling, and
    // only when it is above what is already there (most workgroups see one triangle per pixel).
    if (lid == 0u && group_count > 1u && group_count > msaa_count) atomicMax(msaa_count, group_count);
#elif PRIMARY_MODE == 0
    vec2 pixel = vec2(p.xy) + 0.5;
    vec3 o, d;
    Hit h;
    h.prim = BVH_MISS;
    h.t = 0.0;
    bool valid = inside && camera_subray(p.z, pixel, vec2(size), uint(subsample), o, d);
    cast_primary(p, size, valid, o, d, h);
    if (!inside) return;
    store_cast(p, camera_footprint(p.z, pixel, vec2(size)) > 0.0, h.prim, h.t, uint(subsample));
#else
#if ROUND_TILES
    if (gl_LocalInvocationIndex == 0u) tile_live = 0u;
    barrier();
#endif
    if (inside) {
        int slot = msaa_round < 0 ? 0 : int(max(msaa_count, 1u)) - 1 - msaa_round;
        uvec4 head = slot >= 0 ? HIT(0) : uvec4(0u);  // a round past the count reads no list
        uint n = (head.z >> 8) & 255u, covered = head.z >> 16;
        bool skipped = false;
        if (slot >= 0 && uint(slot) < n) {
            uvec4 e = HIT(slot);
            store(p, e.x, e.z & 255u, uintBitsToFloat(e.w), msaa_weight(p, e.y, covered));
        } else if (slot < 0 || (MSAA_SKIP_EMPTY != 0 && slot > 0)) {
            imageStore(img_weight, p, vec4(ROUND_SKIPPED));  // nothing new: the pixel keeps what it has
            skipped = true;
        } else {
            store(p, BVH_MISS, 0u, 0.0, 0.0);  // nothing in this slot: shaded as background, weighs nothing
        }
#if ROUND_TILES
        if (!skipped) tile_live = 1u;
#endif
    }
#if ROUND_TILES
    barrier();  // the workgroup is a PIXEL_TILE tile: listed once if any of its pixels is not skipped
    if (gl_LocalInvocationIndex == 0u && tile_live != 0u)
        round_tiles[atomicAdd(round_tile_count, 1u)] =
            gl_WorkGroupID.x | (gl_WorkGroupID.y << 14) | (gl_WorkGroupID.z << 28);
#endif
#endif
}
