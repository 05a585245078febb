#version 430
// Tile frustum culling (HVVR's tile frusta, on the GPU; rayvr/accel/frustum.py): one work group per
// tile of TILE_RAYS rays. The group bounds its rays with a conservative frustum, then one
// invocation walks the binary BVH against it and writes the tile's entry list: up to TILE_ENTRIES
// children (parent << 1 | side) whose boxes meet the frustum, a cut of the tree under which lies
// every triangle a ray of the tile can hit. Traversal from the list: bvh2.glsl bvh_traverse_entries.
//
// Where a tile's rays come from:
//   default        TILE_RAYS consecutive rays of the rays SSBO (accel/gpu.py RayTracer), one an invocation;
//   TILE_CAMERA    the frame's camera rays (frame/passes/primary_rays.py, tile culling on): a work group is
//                  a TILE_W x TILE_H pixel block of layer (eye) gl_WorkGroupID.z, an invocation one
//                  pixel, and it bounds every ray primary.comp casts for that pixel: all
//                  CAMERA_SUBSAMPLES sub-rays of its footprint (MSAA/SSAA offsets, thin-lens lens
//                  points) of this round's colour channel set (a cull runs for each set).
//
// Frustum (the math of frustum.py's tile_frusta, which tests check): c = the normalized mean of
// the rays' unit directions, u, v perpendicular to it; slopes su = (d.u)/(d.c), sv likewise. Planes
// n.x <= w: n = u - max(su) c, -u + min(su) c, v - max(sv) c, -v + min(sv) c, each w the largest n.o
// over the rays' origins (so rays from a lens, or from surface points, are covered), and a far plane
// n = c, w = max(c.o + tmax d.c). Every point o + t d, t >= 0, of every ray satisfies them all.
// Slopes and offsets get a relative slack that covers float rounding. A tile whose directions spread
// over a half-space or more (min d.c <= TILE_MIN_COS) is not culled: its list is the root's children.
// Words per tile: [count, entry 0 .. entry TILE_ENTRIES-1]; count 0 for a tile with no valid ray.
// Entries are listed front to back along c (TILE_SORT; 0: tree order, for measuring the difference).
// The cut itself: tile_cut.glsl.
//
// TILE_STAGE (HVVR's block beams, frame/passes/primary_rays.py block culling):
//   0  the frustum, then the cut from the BVH root (one kernel; ray buffers, and frames without blocks);
//   1  the frustum only (camera tiles): tile_planes, and tile_boxes for the block's beam (3 vec4 a
//      tile: the origins' box with w = the largest tmax |d|, its top, the widened slopes (min su,
//      max su, min sv, max sv) about c in the frame u, v below); accel/block_cull.comp follows;
//   2  the cut only, a workgroup of TILE_ENTRIES invocations: the tile's planes from tile_planes, its
//      start list the entries of its block (block_cull.comp's cut, BLOCK_ENTRIES_BINDING) whose boxes
//      meet the tile's frustum instead of the root's children.
#include "../layout.glsl"
#ifndef TILE_RAYS
#define TILE_RAYS DEFAULT_TILE_RAYS
#define TILE_ENTRIES DEFAULT_TILE_ENTRIES
#endif
#ifndef TILE_ENTRIES_BINDING
#define TILE_ENTRIES_BINDING SSBO_TILE_ENTRIES
#define TILE_PLANES_BINDING SSBO_TILE_PLANES
#endif
#ifndef RAYS_BINDING
#define RAYS_BINDING 10
#endif
#ifndef TILE_STAGE
#define TILE_STAGE 0
#endif
#ifndef TILE_BOXES_BINDING
#define TILE_BOXES_BINDING SSBO_TILE_BOXES
#define BLOCK_ENTRIES_BINDING SSBO_BLOCK_ENTRIES
#endif
#if TILE_STAGE == 2
layout(local_size_x = TILE_ENTRIES) in;
#else
layout(local_size_x = TILE_RAYS) in;
#endif

#define TILE_CULL_WRITER 1   // declares tile_entries writable itself
#include "bvh.glsl"
#include "tile_frustum.glsl"
#define CUT_ENTRIES TILE_ENTRIES
#include "tile_cut.glsl"

// TILE_MIN_COS: layout.glsl (rayvr/accel/frustum.py MIN_COS)

layout(std430, binding = TILE_ENTRIES_BINDING) writeonly restrict buffer Entries { uint tile_entries[]; };
#if TILE_STAGE == 2
layout(std430, binding = TILE_PLANES_BINDING) readonly restrict buffer Planes { vec4 tile_planes[]; };
layout(std430, binding = BLOCK_ENTRIES_BINDING) readonly restrict buffer BlockEntries { uint block_entries[]; };
#else
layout(std430, binding = TILE_PLANES_BINDING) writeonly restrict buffer Planes { vec4 tile_planes[]; };  // 5 a tile (tests)
#endif
#if TILE_STAGE == 1
layout(std430, binding = TILE_BOXES_BINDING) writeonly restrict buffer Boxes { vec4 tile_boxes[]; };  // 3 a tile
#endif

#ifdef TILE_CAMERA
#include "../common/camera.glsl"
#include "../rt/primary_ray.glsl"
// every sub-ray of the pixel: with shared channel shading (CHANNEL_SAMPLES 3), all three colour channel sets'
#define TILE_SUBRAYS CAMERA_SUBRAYS
uniform ivec2 image_size;   // per eye

// Sub-ray k of this invocation's pixel, as primary.comp casts it; false: no such ray.
bool tile_ray(uint lid, uint k, out Ray r) {
    ivec3 p = ivec3(ivec2(gl_WorkGroupID.xy) * ivec2(TILE_W, TILE_H) + ivec2(lid % uint(TILE_W), lid / uint(TILE_W)),
                    gl_WorkGroupID.z);
    vec3 o, d;
    bool ok = all(lessThan(p.xy, image_size)) &&
              camera_subray(p.z, vec2(p.xy) + 0.5, vec2(image_size), k, o, d);
    r = ok ? primary_ray(p.z, o, d) : Ray(vec3(0.0), 0.0, vec3(0.0), 0.0);
    return ok && bvh_ray_valid(r);
}
#else
#define TILE_SUBRAYS 1
layout(std430, binding = RAYS_BINDING) readonly restrict buffer Rays { vec4 rays[]; };  // (o, tmin), (d, tmax)
uniform uint ray_count;

bool tile_ray(uint lid, uint k, out Ray r) {
    uint tile = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    uint i = tile * uint(TILE_RAYS) + lid;
    r = Ray(vec3(0.0), 0.0, vec3(0.0), 0.0);
    if (i < ray_count) {
        vec4 a = rays[2u * i], b = rays[2u * i + 1u];
        r = Ray(a.xyz, a.w, b.xyz, b.w);
    }
    return i < ray_count && bvh_ray_valid(r);
}
#endif

#if TILE_STAGE == 1 && !defined(TILE_CAMERA)
#error tile_cull.comp's TILE_STAGE 1 writes the boxes of camera tiles (TILE_CAMERA)
#endif
#if TILE_ENTRIES > TILE_RAYS
#error tile_cull.comp tests a list's entries one an invocation: TILE_ENTRIES must be <= TILE_RAYS
#endif

#if TILE_STAGE == 2
// The cut only (block culling): the tile's planes as stage 1 wrote them, the start list its block's
// entries that meet them (the root's children where the tile was not culled).
void main() {
    uint lid = gl_LocalInvocationID.x;
    uint tile = gl_WorkGroupID.x + gl_NumWorkGroups.x * (gl_WorkGroupID.y + gl_NumWorkGroups.y * gl_WorkGroupID.z);
    uint base = tile * uint(TILE_ENTRIES + 1);
    vec4 planes[5];
    for (int k = 0; k < 5; ++k)
        planes[k] = tile_planes[5u * tile + uint(k)];
    if (planes[4] == vec4(0.0)) {    // no valid ray (the same for the whole group)
        if (lid == 0u)
            tile_entries[base] = 0u;
        return;
    }
    bool fallback = planes[4] == vec4(0.0, 0.0, 0.0, 1.0);
    // The tile's block (BLOCK_TILES_X x BLOCK_TILES_Y tiles) and its list (block_cull.comp).
    uvec3 t = gl_WorkGroupID;
    uvec2 blocks = (gl_NumWorkGroups.xy + uvec2(BLOCK_TILES_X, BLOCK_TILES_Y) - 1u) / uvec2(BLOCK_TILES_X, BLOCK_TILES_Y);
    uint block = t.x / uint(BLOCK_TILES_X) + blocks.x * (t.y / uint(BLOCK_TILES_Y) + blocks.y * t.z);
    uint bbase = block * uint(TILE_ENTRIES + 1), bn = block_entries[bbase];
    bool meets = false;
    if (lid < bn && !fallback) {
        vec3 lo, hi;
        cut_entry_box(block_entries[bbase + 1u + lid], lo, hi);
        meets = frustum_overlaps(planes, lo, hi);
    }
    cut_children[lid] = uvec2(meets ? 1u : 0u, 0u);
    barrier();
    if (lid == 0u) {
        if (fallback || bn == 0u) {   // a tile not culled, or (never for a tile with a ray) an empty block
            cut_start_at_root(planes, fallback);
        } else {
            int count = 0;
            for (uint k = 0u; k < bn; ++k)
                if (cut_children[k].x != 0u)
                    cut[0][count++] = block_entries[bbase + 1u + k];
            cut_count = count;
            cut_opened = true;
        }
    }
    barrier();
    int cur = beam_cut(lid, planes, planes[4].xyz);
    int count = cut_count;
    if (lid == 0u)
        tile_entries[base] = uint(count);
    if (lid < uint(count))
        tile_entries[base + 1u + lid] = cut[cur][lid];
}
#else
#define REDUCE_GROUP TILE_RAYS
#include "group_reduce.glsl"

void main() {
    uint lid = gl_LocalInvocationID.x;
    // tiles in order x, then y, then layer (a frame's; a ray buffer's dispatch has z = 1)
    uint tile = gl_WorkGroupID.x + gl_NumWorkGroups.x * (gl_WorkGroupID.y + gl_NumWorkGroups.y * gl_WorkGroupID.z);
    // Each invocation reduces over its TILE_SUBRAYS rays first (passes over them: the directions'
    // mean, then slopes and extents about it, then the planes' offsets), then the group.
    // Camera tiles make their rays, which costs more than the bounds: there the mean direction, which
    // need only be some direction inside the tile, comes from each pixel's sub-ray 0, and the
    // offsets from the box of the origins (the largest n.o over a box holding them), so the tile's
    // sub-rays are made once (TILE_CAMERA: 3x fewer at 16x). Both stay conservative.
#ifdef TILE_CAMERA
#define TILE_MEAN_RAYS 1
#else
#define TILE_MEAN_RAYS TILE_SUBRAYS
#endif
    Ray r;
    vec4 acc = vec4(0.0);
    for (uint k = 0u; k < uint(TILE_MEAN_RAYS); ++k)
        if (tile_ray(lid, k, r))
            acc += vec4(normalize(r.direction), 1.0);
    REDUCE(acc, 0)
    vec4 sum = red[0];
    barrier();
    uint base = tile * uint(TILE_ENTRIES + 1);
    vec3 c = length(sum.xyz) > 0.0 ? normalize(sum.xyz) : vec3(0.0, 0.0, 1.0);
    vec3 u, v;
    beam_frame(c, u, v);
    const float big = 3.0e38;
    vec4 lo_acc = vec4(big), hi_acc = vec4(-big);
#ifdef TILE_CAMERA
    vec4 o_lo = vec4(big), o_hi = vec4(-big);   // the origins' box; w: whether a ray is valid
#endif
    for (uint k = 0u; k < uint(TILE_SUBRAYS); ++k) {
        if (!tile_ray(lid, k, r))
            continue;
#ifdef TILE_CAMERA
        o_lo = min(o_lo, vec4(r.origin, 0.0));
        o_hi = max(o_hi, vec4(r.origin, 1.0));
#endif
        beam_add_ray(c, u, v, r.origin, r.direction, r.tmax, lo_acc, hi_acc);
    }
    REDUCE(lo_acc, 1)
    vec4 mins = red[0];
    barrier();
    REDUCE(hi_acc, 2)
    vec4 maxs = red[0];
    barrier();
    vec4 slopes = widened_slopes(vec4(mins.y, -mins.z, mins.w, maxs.x));
    vec3 n[4];
    beam_side_normals(c, u, v, slopes, n);
#ifdef TILE_CAMERA
    REDUCE(o_lo, 1)
    vec3 box_lo = red[0].xyz;
    barrier();
    REDUCE(o_hi, 2)
    vec3 box_hi = red[0].xyz;
    sum.w = red[0].w;   // 1: the tile has a valid ray (sub-ray 0 alone may not say so: wide, foveated edges)
    vec4 w = box_offsets(n, box_lo, box_hi);
#else
    vec4 w_acc = vec4(-big);
    for (uint k = 0u; k < uint(TILE_SUBRAYS); ++k)
        if (tile_ray(lid, k, r))
            w_acc = max(w_acc, vec4(dot(n[0], r.origin), dot(n[1], r.origin), dot(n[2], r.origin), dot(n[3], r.origin)));
    REDUCE(w_acc, 2)
    vec4 w = red[0];
#endif
    bool fallback = !(mins.x > TILE_MIN_COS);    // also NaN
    vec4 planes[5];
    beam_planes(c, n, w, maxs, planes);
    if (lid < 5u)
        tile_planes[5u * tile + lid] = sum.w == 0.0 ? vec4(0.0) : (fallback ? vec4(0.0, 0.0, 0.0, 1.0) : planes[lid]);
#if TILE_STAGE == 1
    // the block's beam reads the origins' box, how far the rays reach, and the widened slopes
    if (lid == 0u) {
        tile_boxes[3u * tile] = vec4(box_lo, maxs.w);
        tile_boxes[3u * tile + 1u] = vec4(box_hi, 0.0);
        tile_boxes[3u * tile + 2u] = slopes;
    }
#else
    if (sum.w == 0.0) {              // no valid ray: nothing to trace (the same for the whole group)
        if (lid == 0u)
            tile_entries[base] = 0u;
        return;
    }
    if (lid == 0u)
        cut_start_at_root(planes, fallback);
    barrier();
    int cur = beam_cut(lid, planes, c);
    int count = cut_count;
    if (lid == 0u)
        tile_entries[base] = uint(count);
    if (lid < uint(count))
        tile_entries[base + 1u + lid] = cut[cur][lid];
#endif
}
#endif
