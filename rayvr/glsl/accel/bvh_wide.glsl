// Wide BVH (BVH_WIDTH 4 or 8 children, quantized boxes; rayvr/accel/wide.py): bvh_traverse for bvh.glsl.
//   bvh_wide: BVH_NODE_VEC4 uvec4 per node: origin.xyz bits, (ex, ey, ez, child count) bytes; six
//             planes of one byte per child (lo.x hi.x lo.y hi.y lo.z hi.z), plane = origin + q * 2^(e-127);
//             one byte per child: leaf triangle count (0 = internal); one word per child: wide node
//             index (internal) or first triangle slot (leaf). Children are packed first.
// BVH_ORDERED 1: a closest-hit ray visits the entered internal children nearest first (a sorting
// network over the entry distances); 0: in stored order. Any-hit rays never sort (BVH_ORDERED_ANY).
#ifndef RAYVR_ACCEL_BVH_WIDE_GLSL
#define RAYVR_ACCEL_BVH_WIDE_GLSL

#ifndef BVH_NODE_VEC4
#define BVH_NODE_VEC4 (BVH_WIDTH == 4 ? 4 : 7)   // wide.node_words(width) / 4
#endif
#ifndef BVH_ORDERED
#define BVH_ORDERED 1
#endif
#ifndef BVH_ORDERED_ANY
#define BVH_ORDERED_ANY 0
#endif
#define BVH_WQ (BVH_WIDTH / 4)   // words per byte plane

layout(std430, binding = BVH_NODES_BINDING) readonly restrict buffer BvhWide { uvec4 bvh_wide[]; };

#define BVH_WORD(w) nd[(w) >> 2][(w) & 3]
#define BVH_BYTE(w, i) float((BVH_WORD((w) + ((i) >> 2)) >> (8u * uint((i) & 3))) & 0xFFu)
#define BVH_CSWAP(i, j) if (cd[j] < cd[i]) { float td = cd[i]; cd[i] = cd[j]; cd[j] = td; \
                                             uint ti = ci[i]; ci[i] = ci[j]; ci[j] = ti; }

bool bvh_traverse(Ray r, bool any_hit, inout Hit h) {
    RayShear s;
    vec3 inv;
    if (!bvh_begin(r, h, s, inv))
        return false;
    BVH_LOCAL_STACK
    int sp = 0;
    uint node = 0u;
    while (true) {
        uvec4 nd[BVH_NODE_VEC4];
        for (int k = 0; k < BVH_NODE_VEC4; ++k)
            nd[k] = bvh_wide[int(node) * BVH_NODE_VEC4 + k];
        vec3 org = uintBitsToFloat(nd[0].xyz);
        uint e = nd[0].w;
        vec3 scale = uintBitsToFloat(uvec3(e & 0xFFu, (e >> 8) & 0xFFu, (e >> 16) & 0xFFu) << 23u);
        int nchild = int(e >> 24);
        float cd[BVH_WIDTH];   // entry distance of each entered internal child (3e38: none)
        uint ci[BVH_WIDTH];
        for (int i = 0; i < BVH_WIDTH; ++i) {
            cd[i] = 3.0e38;
            ci[i] = BVH_MISS;
            if (i >= nchild)
                continue;
            vec3 lo = org + vec3(BVH_BYTE(4, i), BVH_BYTE(4 + 2 * BVH_WQ, i), BVH_BYTE(4 + 4 * BVH_WQ, i)) * scale;
            vec3 hi = org + vec3(BVH_BYTE(4 + BVH_WQ, i), BVH_BYTE(4 + 3 * BVH_WQ, i), BVH_BYTE(4 + 5 * BVH_WQ, i)) * scale;
            float tn;
            if (!bvh_slab(r.origin, inv, lo, hi, r.tmin, h.t, tn))
                continue;
            int count = int(BVH_BYTE(4 + 6 * BVH_WQ, i));
            uint index = BVH_WORD(4 + 7 * BVH_WQ + i);
            if (count > 0) {
                if (bvh_leaf(s, int(index), count, r.tmin, any_hit, h) && any_hit)
                    return true;
            } else {
                cd[i] = tn;
                ci[i] = index;
            }
        }
        if (any_hit ? BVH_ORDERED_ANY != 0 : BVH_ORDERED != 0) {
#if BVH_WIDTH == 4
            BVH_CSWAP(0, 1) BVH_CSWAP(2, 3) BVH_CSWAP(0, 2) BVH_CSWAP(1, 3) BVH_CSWAP(1, 2)
#else
            BVH_CSWAP(0, 2) BVH_CSWAP(1, 3) BVH_CSWAP(4, 6) BVH_CSWAP(5, 7) BVH_CSWAP(0, 4)
            BVH_CSWAP(1, 5) BVH_CSWAP(2, 6) BVH_CSWAP(3, 7) BVH_CSWAP(0, 1) BVH_CSWAP(2, 3)
            BVH_CSWAP(4, 5) BVH_CSWAP(6, 7) BVH_CSWAP(2, 4) BVH_CSWAP(3, 5) BVH_CSWAP(1, 4)
            BVH_CSWAP(3, 6) BVH_CSWAP(1, 2) BVH_CSWAP(3, 4) BVH_CSWAP(5, 6)
#endif
        }
        // Farthest first onto the stack; the nearest (or first stored) is visited next without a
        // push and pop. Children whose entry lies beyond a hit found in this node's leaves drop out.
        int next = -1;
        for (int i = BVH_WIDTH - 1; i >= 0; --i)
            if (ci[i] != BVH_MISS && cd[i] <= h.t) {
                if (next >= 0)
                    bvh_stack[sp++] = next;
                next = int(ci[i]);
            }
        if (next >= 0) {
            node = uint(next);
        } else {
            if (sp == 0)
                break;
            node = uint(bvh_stack[--sp]);
        }
    }
    return h.prim != BVH_MISS;
}

#undef BVH_WORD
#undef BVH_BYTE
#undef BVH_CSWAP
#endif
