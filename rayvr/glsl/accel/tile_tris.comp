#version 430
// Tile triangle lists (HVVR's tile beams, the second stage after tile_cull.comp's entry cut; frame/passes/
// primary_rays.py): one work group per frame tile walks the BVH from the tile's entries against its
// frustum, breadth first (one sweep a tree level, a node an invocation), down to the triangles that
// meet the frustum, and lists them nearest first along the tile's central direction c. rt/primary.comp
// (TILE_TRIS_BINDING) then tests every ray of the tile against the list from workgroup memory.
//
// Words per tile (uvec2): [0] = (count, 0), then count entries (BVH triangle slot, key bits), key =
// a lower bound of c.x over the triangle (its nearest vertex along c, less the rounding slack),
// ascending, ties by slot. count = TILE_OVERFLOW when the list would exceed TILE_TRIS triangles or
// the sweep TILE_FRONT nodes, or the tile was not culled (its rays spread over a half-space): its
// rays then walk the BVH from the tile's entries (bvh2.glsl trace_closest_in_tile). Never a
// dropped triangle: a list holds every triangle of the tile's frustum, or the tile has none.
#include "../layout.glsl"
#ifndef TILE_TRIS                 // the pass sets them (frame/passes/primary_rays.py)
#define TILE_TRIS DEFAULT_TILE_TRIS
#define TILE_TRIS_BINDING SSBO_TILE_TRIS
#endif
#ifndef TILE_ENTRIES_BINDING
#define TILE_RAYS DEFAULT_TILE_RAYS
#define TILE_ENTRIES DEFAULT_TILE_ENTRIES
#define TILE_ENTRIES_BINDING SSBO_TILE_ENTRIES
#define TILE_PLANES_BINDING SSBO_TILE_PLANES
#endif
layout(local_size_x = TILE_LIST_GROUP) in;
#include "bvh.glsl"           // BVH_WIDTH 2, with TILE_ENTRIES_BINDING: tile_entries, tile_planes
#include "tile_frustum.glsl"

layout(std430, binding = TILE_TRIS_BINDING) writeonly restrict buffer TileTris { uvec2 tile_tris[]; };

shared uint front[2][TILE_FRONT];  // the sweep's nodes and the next sweep's, as (parent << 1 | side)
shared uint front_n[2];
shared uint tri_n;
shared uint overflowed;
shared float tri_key[TILE_TRIS];
shared uint tri_slot[TILE_TRIS];

// The triangle's least c.x, lowered by its rounding (rt/primary.comp compares it with a ray's reach).
float tri_lower_key(vec3 c, vec3 a, vec3 b, vec3 d) {
    float lo = min(min(dot(c, a), dot(c, b)), dot(c, d));
    return lo - TILE_SLACK * dot(abs(c), max(max(abs(a), abs(b)), abs(d)));
}

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint tile = gl_WorkGroupID.x + gl_NumWorkGroups.x * (gl_WorkGroupID.y + gl_NumWorkGroups.y * gl_WorkGroupID.z);
    uint head = tile * uint(TILE_TRIS + 1), entries = tile * uint(TILE_ENTRIES + 1);
    uint n_entries = tile_entries[entries];
    vec4 planes[5];
    for (int k = 0; k < 5; ++k)
        planes[k] = tile_planes[5u * tile + uint(k)];
    bool not_culled = planes[4] == vec4(0.0, 0.0, 0.0, 1.0);   // tile_cull.comp's fallback mark
    if (n_entries == 0u || not_culled) {   // uniform: the same words for the whole group
        if (lid == 0u)
            tile_tris[head] = uvec2(n_entries == 0u ? 0u : TILE_OVERFLOW, 0u);
        return;
    }
    if (lid == 0u) {
        front_n[0] = n_entries;
        front_n[1] = 0u;
        tri_n = 0u;
        overflowed = 0u;
    }
    if (lid < n_entries)
        front[0][lid] = tile_entries[entries + 1u + lid];
    barrier();
    vec3 c = planes[4].xyz;
    int cur = 0;
    for (int sweep = 0; ; ++sweep) {
        uint n = front_n[cur];
        if (n == 0u || overflowed != 0u)   // uniform: shared, read after a barrier
            break;
        if (sweep == BEAM_MAX_SWEEPS) {    // deeper than any valid tree (a guard): per ray instead
            if (lid == 0u)
                tile_tris[head] = uvec2(TILE_OVERFLOW, 0u);
            return;
        }
        for (uint i = lid; i < n; i += uint(TILE_LIST_GROUP)) {
            uint e = front[cur][i];
            int parent = int(e >> 1u), side = int(e & 1u);
            ivec4 m = floatBitsToInt(bvh_nodes[4 * parent + 3]);
            int index = side == 0 ? m.x : m.y, count = side == 0 ? m.z : m.w;
            if (count > 0) {         // a leaf: its triangles that meet the frustum
                for (int t = index; t < index + count; ++t) {
                    vec3 a = bvh_tris[3 * t].xyz, b = bvh_tris[3 * t + 1].xyz, d = bvh_tris[3 * t + 2].xyz;
                    if (!frustum_meets_triangle(planes, a, b, d))
                        continue;
                    uint k = atomicAdd(tri_n, 1u);
                    if (k < uint(TILE_TRIS)) {
                        tri_slot[k] = uint(t);
                        tri_key[k] = tri_lower_key(c, a, b, d);
                    } else {
                        overflowed = 1u;
                    }
                }
            } else {                 // internal: its children that meet the frustum, to the next sweep
                vec4 n0 = bvh_nodes[4 * index], n1 = bvh_nodes[4 * index + 1], n2 = bvh_nodes[4 * index + 2];
                for (int cs = 0; cs < 2; ++cs) {
                    vec3 lo, hi;
                    bvh2_child_box(n0, n1, n2, cs, lo, hi);
                    if (!frustum_overlaps(planes, lo, hi))
                        continue;
                    uint k = atomicAdd(front_n[1 - cur], 1u);
                    if (k < uint(TILE_FRONT))
                        front[1 - cur][k] = (uint(index) << 1u) | uint(cs);
                    else
                        overflowed = 1u;
                }
            }
        }
        barrier();
        if (lid == 0u)
            front_n[cur] = 0u;
        barrier();
        cur = 1 - cur;
    }
    if (overflowed != 0u) {
        if (lid == 0u)
            tile_tris[head] = uvec2(TILE_OVERFLOW, 0u);
        return;
    }
    // Bitonic sort of (key, slot), padded to a power of two with keys past any reach.
    uint count = tri_n, size = 1u;
    while (size < count)
        size <<= 1u;
    for (uint i = count + lid; i < size; i += uint(TILE_LIST_GROUP)) {
        tri_key[i] = 3.0e38;
        tri_slot[i] = 0xFFFFFFFFu;
    }
    barrier();
    for (uint k = 2u; k <= size; k <<= 1u) {
        for (uint j = k >> 1u; j > 0u; j >>= 1u) {
            for (uint i = lid; i < size; i += uint(TILE_LIST_GROUP)) {
                uint l = i ^ j;
                if (l <= i)
                    continue;
                float ki = tri_key[i], kl = tri_key[l];
                uint si = tri_slot[i], sl = tri_slot[l];
                bool greater = ki > kl || (ki == kl && si > sl);
                if (greater == ((i & k) == 0u)) {   // ascending where bit k of i is 0
                    tri_key[i] = kl;
                    tri_key[l] = ki;
                    tri_slot[i] = sl;
                    tri_slot[l] = si;
                }
            }
            barrier();
        }
    }
    for (uint i = lid; i < count; i += uint(TILE_LIST_GROUP))
        tile_tris[head + 1u + i] = uvec2(tri_slot[i], floatBitsToUint(tri_key[i]));
    if (lid == 0u)
        tile_tris[head] = uvec2(count, 0u);
}
