// The child-pair binary BVH (rayvr/accel/bvh.py, the reference layout): bvh_traverse for bvh.glsl.
//   bvh_nodes: 4 vec4 per node: L box (x lo/hi, y lo/hi, z lo/hi), R box, then int bits
//              (L index, R index, L count, R count); count 0 = internal child at node `index`,
//              count > 0 = leaf of `count` triangles starting at slot `index`. Node 0 is the root.
#ifndef RAYVR_ACCEL_BVH2_GLSL
#define RAYVR_ACCEL_BVH2_GLSL

layout(std430, binding = BVH_NODES_BINDING) readonly restrict buffer BvhNodes { vec4 bvh_nodes[]; };

// Stack traversal: test both children of a node; leaf children are intersected at once, so only
// internal nodes are pushed; with two internal children hit, go to the nearer, push the farther.
bool bvh_traverse(Ray r, bool any_hit, inout Hit h) {
    RayShear s;
    vec3 inv;
    if (!bvh_begin(r, h, s, inv))
        return false;
    BVH_LOCAL_STACK
    int sp = 0;
    int node = 0;
    while (true) {
        vec4 n0 = bvh_nodes[4 * node];
        vec4 n1 = bvh_nodes[4 * node + 1];
        vec4 n2 = bvh_nodes[4 * node + 2];
        ivec4 m = floatBitsToInt(bvh_nodes[4 * node + 3]);
        float tl, tr;
        bool hl = bvh_slab(r.origin, inv, vec3(n0.x, n0.z, n1.x), vec3(n0.y, n0.w, n1.y), r.tmin, h.t, tl);
        bool hr = bvh_slab(r.origin, inv, vec3(n1.z, n2.x, n2.z), vec3(n1.w, n2.y, n2.w), r.tmin, h.t, tr);
        if (hl && m.z > 0) {
            if (bvh_leaf(s, m.x, m.z, r.tmin, any_hit, h) && any_hit)
                return true;
            hl = false;
            hr = hr && tr <= h.t;
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
    return h.prim != BVH_MISS;
}

#endif
