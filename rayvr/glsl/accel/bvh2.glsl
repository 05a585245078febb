// The child-pair binary BVH (rayvr/accel/bvh.py, the reference layout): bvh_traverse for bvh.glsl.
//   bvh_nodes: 4 vec4 per node: L box (x lo/hi, y lo/hi, z lo/hi), R box, then int bits
//              (L index, R index, L count, R count); count 0 = internal child at node `index`,
//              count > 0 = leaf of `count` triangles starting at slot `index`. Node 0 is the root.
#ifndef RAYVR_ACCEL_BVH2_GLSL
#define RAYVR_ACCEL_BVH2_GLSL

layout(std430, binding = BVH_NODES_BINDING) readonly restrict buffer BvhNodes { vec4 bvh_nodes[]; };

// Box of child `side` (0 left, 1 right) of a node's fetched vec4s.
void bvh2_child_box(vec4 n0, vec4 n1, vec4 n2, int side, out vec3 lo, out vec3 hi) {
    lo = side == 0 ? vec3(n0.x, n0.z, n1.x) : vec3(n1.z, n2.x, n2.z);
    hi = side == 0 ? vec3(n0.y, n0.w, n1.y) : vec3(n1.w, n2.y, n2.w);
}

// Stack traversal of the subtree under internal node `node`: test both children of a node; leaf
// children are intersected at once, so only internal nodes are pushed; with two internal children
// hit, go to the nearer, push the farther. True when an any-hit ray found its hit.
bool bvh2_walk(Ray r, RayShear s, vec3 inv, bool any_hit, inout Hit h, int node) {
    BVH_LOCAL_STACK
    int sp = 0;
    while (true) {
        BVH_WORK(0);
        vec4 n0 = bvh_nodes[4 * node];
        vec4 n1 = bvh_nodes[4 * node + 1];
        vec4 n2 = bvh_nodes[4 * node + 2];
        ivec4 m = floatBitsToInt(bvh_nodes[4 * node + 3]);
        float tl, tr;
        vec3 lo, hi;
        bvh2_child_box(n0, n1, n2, 0, lo, hi);
        bool hl = bvh_slab(r.origin, inv, lo, hi, r.tmin, h.t, tl);
        bvh2_child_box(n0, n1, n2, 1, lo, hi);
        bool hr = bvh_slab(r.origin, inv, lo, hi, r.tmin, h.t, tr);
        if (hl && m.z > 0) {
            if (bvh_leaf(s, m.x, m.z, r.tmin, any_hit, h) && any_hit)
                return true;
            hl = false;
            hr = hr && tr <= bvh_reach(h.t);
        }
        if (hr && m.w > 0) {
            if (bvh_leaf(s, m.y, m.w, r.tmin, any_hit, h) && any_hit)
                return true;
            hr = false;
        }
        if (hl && hr) {
            bool left_first = tl <= tr;
            bvh_stack[sp++] = left_first ? m.y : m.x;
            node = left_first ? m.x : m.y;
        } else if (hl) {
            node = m.x;
        } else if (hr) {
            node = m.y;
        } else {
            if (sp == 0)
                break;
            node = bvh_stack[--sp];
        }
    }
    return false;
}

bool bvh_traverse(Ray r, bool any_hit, inout Hit h) {
    RayShear s;
    vec3 inv;
    if (!bvh_begin(r, h, s, inv))
        return false;
    return bvh2_walk(r, s, inv, any_hit, h, 0) || h.prim != BVH_MISS;
}

#ifndef TILE_SORT
#define TILE_SORT 1   // tile_cull.comp lists a tile's entries front to back along its central direction
#endif
// TILE_SLACK (layout.glsl, rayvr/accel/frustum.py SLACK): relative slack of the tile tests for float rounding

#if defined(TILE_ENTRIES_BINDING) && !defined(TILE_CULL_WRITER)
// Tile frustum culling (rayvr/accel/frustum.py, tile_cull.comp): a tile's entry list names the
// children (parent node << 1 | side) whose boxes meet the tile's frustum, a cut of the tree that
// covers every triangle a ray of the tile can hit. The ray tests each entry's box, then walks it.
layout(std430, binding = TILE_ENTRIES_BINDING) readonly restrict buffer TileEntries { uint tile_entries[]; };
layout(std430, binding = TILE_PLANES_BINDING) readonly restrict buffer TilePlanes { vec4 tile_planes[]; };

bool bvh_traverse_entries(Ray r, bool any_hit, inout Hit h, uint tile) {
    RayShear s;
    vec3 inv;
    if (!bvh_begin(r, h, s, inv))
        return false;
    uint base = tile * uint(TILE_ENTRIES + 1), n = tile_entries[base];
#if TILE_SORT
    // Entries come nearest first along the tile's central direction c (its far plane's normal; 0
    // for a tile not culled). Once an entry's box lies wholly beyond c.x of the ray's points up to
    // its closest hit, so does every later one: stop. Exact: a hit at t <= h.t lies in its box at
    // c.x = c.o + t c.d <= reach (the slack covers rounding; a tie at h.t is not beyond).
    vec3 c = tile_planes[5u * tile + 4u].xyz;
    float co = dot(c, r.origin), cd = dot(c, r.direction);
#endif
    for (uint k = 0u; k < n; ++k) {
        BVH_WORK(1);
        uint e = tile_entries[base + 1u + k];
        int parent = int(e >> 1u), side = int(e & 1u);
        vec3 lo, hi;
        bvh2_child_box(bvh_nodes[4 * parent], bvh_nodes[4 * parent + 1], bvh_nodes[4 * parent + 2], side, lo, hi);
#if TILE_SORT
        vec3 mid = 0.5 * (lo + hi), ext = 0.5 * (hi - lo);
        float near_c = dot(c, mid) - dot(abs(c), ext), reach = co + h.t * cd;
        if (near_c > reach + TILE_SLACK * (dot(abs(c), abs(mid) + abs(ext)) + abs(co) + abs(h.t * cd)))
            break;
#endif
        float tn;
        if (!bvh_slab(r.origin, inv, lo, hi, r.tmin, h.t, tn))
            continue;
        ivec4 m = floatBitsToInt(bvh_nodes[4 * parent + 3]);
        int index = side == 0 ? m.x : m.y, count = side == 0 ? m.z : m.w;
        if (count > 0 ? bvh_leaf(s, index, count, r.tmin, any_hit, h) : bvh2_walk(r, s, inv, any_hit, h, index))
            if (any_hit)
                return true;
    }
    return h.prim != BVH_MISS;
}

// From tile `tile`'s entries.
bool trace_closest_in_tile(Ray r, uint tile, out Hit h) {
    return bvh_traverse_entries(r, false, h, tile);
}

// The tile's entries for ray `ray` of a ray buffer (TILE_RAYS consecutive rays a tile).
bool trace_closest_tile(Ray r, uint ray, out Hit h) {
    return trace_closest_in_tile(r, ray / uint(TILE_RAYS), h);
}

bool trace_any_tile(Ray r, uint ray) {
    Hit h;
    return bvh_traverse_entries(r, true, h, ray / uint(TILE_RAYS));
}
#endif

#endif
