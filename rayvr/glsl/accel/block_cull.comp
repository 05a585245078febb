#version 430
// Block beams (HVVR's block culling, the first stage of tile-culled primary visibility with blocks;
// frame/passes/primary_rays.py): one work group per block of BLOCK_TILES_X x BLOCK_TILES_Y frame
// tiles, one invocation per tile. The block's frustum holds every tile's: tile_cull.comp's TILE_STAGE
// 1 wrote each tile's planes and, in tile_boxes, its rays' origin box, reach (the largest tmax |d|)
// and direction slopes (widened: su in [x, y], sv in [z, w] about the tile's central direction c,
// tile_planes[4].xyz, in the frame u, v of tile_cull.comp). Every ray direction of a tile is then a
// positive multiple of a point c + su u + sv v of that slope rectangle, so of a convex combination of
// its four corners: the block's cone is fitted to the corners of all its tiles, about their normalized
// mean direction C (slopes about C, as tile_cull.comp fits rays), its side planes offset to hold the
// union of the origin boxes, its far plane C.x <= max C.o + reach. A block whose corners spread over a
// half-space or more (min cosine to C <= TILE_MIN_COS) or holding a tile not culled is not culled:
// its list is the root's children. The cut (tile_cut.glsl) then opens the tree from the root down
// to at most TILE_ENTRIES entries, front to back along C; tile_cull.comp's TILE_STAGE 2 starts each
// tile's cut from the block's entries that meet the tile's frustum.
// Words per block: [count, entry 0 .. entry TILE_ENTRIES-1], as tile_entries; count 0 for a block
// without a valid ray. block_planes: 5 vec4 a block, as tile_planes (tests).
#include "../layout.glsl"   // BLOCK_TILES = BLOCK_TILES_X * BLOCK_TILES_Y
#ifndef TILE_ENTRIES_BINDING   // the pass sets them (frame/passes/primary_rays.py)
#define TILE_RAYS DEFAULT_TILE_RAYS
#define TILE_ENTRIES DEFAULT_TILE_ENTRIES
#define TILE_ENTRIES_BINDING SSBO_TILE_ENTRIES
#define TILE_PLANES_BINDING SSBO_TILE_PLANES
#endif
#ifndef TILE_BOXES_BINDING
#define TILE_BOXES_BINDING SSBO_TILE_BOXES
#define BLOCK_ENTRIES_BINDING SSBO_BLOCK_ENTRIES
#define BLOCK_PLANES_BINDING SSBO_BLOCK_PLANES
#endif
layout(local_size_x = BLOCK_TILES) in;

#include "bvh.glsl"   // with TILE_ENTRIES_BINDING: tile_planes (read)
#include "tile_frustum.glsl"
#define CUT_ENTRIES TILE_ENTRIES
#include "tile_cut.glsl"

#if TILE_ENTRIES > BLOCK_TILES
#error block_cull.comp tests a list's entries one an invocation: TILE_ENTRIES must be <= its tiles
#endif

layout(std430, binding = TILE_BOXES_BINDING) readonly restrict buffer Boxes { vec4 tile_boxes[]; };
layout(std430, binding = BLOCK_ENTRIES_BINDING) writeonly restrict buffer BlockEntries { uint block_entries[]; };
layout(std430, binding = BLOCK_PLANES_BINDING) writeonly restrict buffer BlockPlanes { vec4 block_planes[]; };
uniform uvec2 tile_count;   // tiles of a layer (across, down)

#define REDUCE_GROUP BLOCK_TILES
#include "group_reduce.glsl"

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint block = gl_WorkGroupID.x + gl_NumWorkGroups.x * (gl_WorkGroupID.y + gl_NumWorkGroups.y * gl_WorkGroupID.z);
    uvec2 t = gl_WorkGroupID.xy * uvec2(BLOCK_TILES_X, BLOCK_TILES_Y) + uvec2(lid % uint(BLOCK_TILES_X), lid / uint(BLOCK_TILES_X));
    uint tile = t.x + tile_count.x * (t.y + tile_count.y * gl_WorkGroupID.z);
    bool here = all(lessThan(t, tile_count));
    vec4 c4 = here ? tile_planes[5u * tile + 4u] : vec4(0.0);
    bool has_ray = c4 != vec4(0.0), not_culled = c4 == vec4(0.0, 0.0, 0.0, 1.0);
    bool culled = has_ray && !not_culled;
    // the mean of the culled tiles' central directions; how many tiles have a ray, and are not culled
    REDUCE(vec4(culled ? c4.xyz : vec3(0.0), has_ray ? 1.0 : 0.0), 0)
    vec4 sum = red[0];
    barrier();
    REDUCE(vec4(not_culled ? 1.0 : 0.0), 0)
    bool fallback = red[0].x > 0.0;
    barrier();
    uint base = block * uint(TILE_ENTRIES + 1);
    vec3 C = length(sum.xyz) > 0.0 ? normalize(sum.xyz) : vec3(0.0, 0.0, 1.0);
    vec3 U, V;
    beam_frame(C, U, V);
    const float big = 3.0e38;
    vec4 lo_acc = vec4(big), hi_acc = vec4(-big), o_lo = vec4(big), o_hi = vec4(-big);
    if (culled) {
        vec3 c = c4.xyz;
        vec3 u, v;
        beam_frame(c, u, v);
        vec4 box_lo = tile_boxes[3u * tile], box_hi = tile_boxes[3u * tile + 1u], s = tile_boxes[3u * tile + 2u];
        for (int k = 0; k < 4; ++k) {
            vec3 d = normalize(c + ((k & 1) == 0 ? s.x : s.y) * u + ((k & 2) == 0 ? s.z : s.w) * v);
            float dc = dot(d, C);
            float su = dot(d, U) / dc, sv = dot(d, V) / dc;
            lo_acc = min(lo_acc, vec4(dc, su, -su, sv));
            hi_acc = max(hi_acc, vec4(sv, 0.0, 0.0, 0.0));
        }
        o_lo = vec4(box_lo.xyz, 0.0);
        o_hi = vec4(box_hi.xyz, box_lo.w);   // w: the tile's reach
        // the far plane's offset: C.o over the box, plus the reach
        vec3 bc = 0.5 * (box_lo.xyz + box_hi.xyz), be = 0.5 * (box_hi.xyz - box_lo.xyz);
        hi_acc.y = dot(C, bc) + dot(abs(C), be) + box_lo.w;
        hi_acc.z = dot(abs(box_lo.xyz), vec3(1.0)) + dot(abs(box_hi.xyz), vec3(1.0));
    }
    REDUCE(lo_acc, 1)
    vec4 mins = red[0];
    barrier();
    REDUCE(hi_acc, 2)
    vec4 maxs = red[0];
    barrier();
    REDUCE(o_lo, 1)
    vec3 box_lo = red[0].xyz;
    barrier();
    REDUCE(o_hi, 2)
    vec3 box_hi = red[0].xyz;
    barrier();
    fallback = fallback || !(mins.x > TILE_MIN_COS);   // also NaN
    vec3 n[4];
    beam_side_normals(C, U, V, widened_slopes(vec4(mins.y, -mins.z, mins.w, maxs.x)), n);
    vec4 planes[5];
    beam_planes(C, n, box_offsets(n, box_lo, box_hi), maxs, planes);
    if (lid < 5u)
        block_planes[5u * block + lid] = sum.w == 0.0 ? vec4(0.0) : (fallback ? vec4(0.0, 0.0, 0.0, 1.0) : planes[lid]);
    if (sum.w == 0.0) {              // no tile with a ray (the same for the whole group)
        if (lid == 0u)
            block_entries[base] = 0u;
        return;
    }
    if (lid == 0u)
        cut_start_at_root(planes, fallback);
    barrier();
    int cur = beam_cut(lid, planes, C);
    int count = cut_count;
    if (lid == 0u)
        block_entries[base] = uint(count);
    if (lid < uint(count))
        block_entries[base + 1u + lid] = cut[cur][lid];
}
