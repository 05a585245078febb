// Wide BVH (BVH_WIDTH 4 or 8 children, quantized boxes; rayvr/accel/wide.py): bvh_traverse for bvh.glsl.
//   bvh_wide: BVH_NODE_VEC4 uvec4 per node: origin.xyz bits, (ex, ey, ez, child count) bytes; six
//             planes of one byte per child (lo.x hi.x lo.y hi.y lo.z hi.z), plane = origin + q * 2^(e-127);
//             one byte per child: leaf triangle count (0 = internal); one word per child: wide node
//             index (internal) or first triangle slot (leaf). Children are packed first.
// BVH_ORDERED 1: a closest-hit ray enters its nearest internal child first; 0: the first stored.
// Any-hit rays follow BVH_ORDERED (BVH_ORDERED_ANY), as bvh2 orders them; on the GPU this changed
// nothing measurable against stored order (shadow rays 0.78x / 0.92x of bvh2 in room / Sponza both
// ways; docs/design.md).
//
// Why it looks like this (the GPU ran an earlier form with per-child arrays, a sorting network and a
// push per entered child at 0.05-0.17x of bvh2): every child test is written out by the preprocessor
// (BVH_CHILD_TEST), so the node's words and the children's entry distances are indexed by constants
// and stay in registers; leaves and the next child are picked from bit masks (findLSB), their words
// read again from the buffer (an L1 hit) instead of from a dynamically indexed array; and the stack
// holds one entry per node group, (node << 8 | mask of its entered children not yet visited), as in
// Ylitie et al. 2017, so it is at most the tree's depth deep (wide.WideBvh.group_stack_bound).
#ifndef RAYVR_ACCEL_BVH_WIDE_GLSL
#define RAYVR_ACCEL_BVH_WIDE_GLSL

#ifndef BVH_NODE_VEC4
#define BVH_NODE_VEC4 (BVH_WIDTH == 4 ? 4 : 7)   // wide.node_words(width) / 4
#endif
#ifndef BVH_ORDERED
#define BVH_ORDERED 1
#endif
#ifndef BVH_ORDERED_ANY
#define BVH_ORDERED_ANY BVH_ORDERED
#endif
#define BVH_WQ (BVH_WIDTH / 4)   // words per byte plane

layout(std430, binding = BVH_NODES_BINDING) readonly restrict buffer BvhWide { uvec4 bvh_wide[]; };

// Word w of the fetched node (w a constant), byte i of plane p, and a node's word read from the buffer.
#define BVH_WORD(w) nd[(w) >> 2][(w) & 3]
#define BVH_BYTE(p, i) ((BVH_WORD(4 + (p) * BVH_WQ + ((i) >> 2)) >> (8u * uint((i) & 3))) & 0xFFu)
#define BVH_NODE_WORD(n, w) bvh_wide[int(n) * BVH_NODE_VEC4 + ((w) >> 2)][(w) & 3]
#define BVH_CHILD_INDEX(n, i) BVH_NODE_WORD(n, 4 + 7 * BVH_WQ + (i))

// Child i's box against the ray: bit i of `entered` (and of `leaves` for a leaf child), tn[i] its entry.
// The ray is carried into the node's quantized frame once a node (Ylitie et al. 2017): a plane
// org + q * scale is crossed at t = q * (scale / d) + (org - o) / d, one fused multiply-add a plane,
// with the near/far byte planes picked per node by the direction's signs (wnear/wfar). Rounding in
// (org - o) / d is absolute, not relative to t, so the node's bases are widened by BVH_MARGIN of
// their size (> 4 ulp): the test stays conservative, and only triangles decide hits.
#define BVH_MARGIN 1.0e-6
#define BVH_NEAR(a, i) float((wnear[a][(i) >> 2] >> (8u * uint((i) & 3))) & 0xFFu)
#define BVH_FAR(a, i) float((wfar[a][(i) >> 2] >> (8u * uint((i) & 3))) & 0xFFu)
#define BVH_CHILD_TEST(i) \
    if (uint(i) < nchild) { \
        vec3 t0 = vec3(BVH_NEAR(0, i), BVH_NEAR(1, i), BVH_NEAR(2, i)) * step + base_near; \
        vec3 t1 = vec3(BVH_FAR(0, i), BVH_FAR(1, i), BVH_FAR(2, i)) * step + base_far; \
        tn[i] = max(max(t0.x, t0.y), max(t0.z, r.tmin)); \
        if (tn[i] <= min(min(min(t1.x, t1.y), t1.z) * 1.00000024, bvh_reach(h.t))) { \
            entered |= 1u << (i); \
            if (BVH_BYTE(6, i) != 0u) leaves |= 1u << (i); \
        } \
    }
// Internal child i: dropped when it starts beyond a hit found in this node's leaves; else the nearest.
#define BVH_CHILD_NEAREST(i) \
    if ((inner & (1u << (i))) != 0u) { \
        if (tn[i] > bvh_reach(h.t)) inner &= ~(1u << (i)); \
        else if (tn[i] < nearest_t) { nearest_t = tn[i]; nearest = (i); } \
    }

bool bvh_traverse(Ray r, bool any_hit, inout Hit h) {
    RayShear s;
    vec3 inv;
    if (!bvh_begin(r, h, s, inv))
        return false;
    BVH_LOCAL_STACK
    int sp = 0;
    uint node = 0u;
    bool ordered = any_hit ? BVH_ORDERED_ANY != 0 : BVH_ORDERED != 0;
    while (true) {
        uvec4 nd[BVH_NODE_VEC4];
        for (int k = 0; k < BVH_NODE_VEC4; ++k)
            nd[k] = bvh_wide[int(node) * BVH_NODE_VEC4 + k];
        uint e = nd[0].w;
        vec3 scale = uintBitsToFloat(uvec3(e & 0xFFu, (e >> 8) & 0xFFu, (e >> 16) & 0xFFu) << 23u);
        uint nchild = e >> 24;
        vec3 step = scale * inv;   // exact: scale is a power of two
        vec3 base = (uintBitsToFloat(nd[0].xyz) - r.origin) * inv;
        vec3 base_near = base - abs(base) * BVH_MARGIN, base_far = base + abs(base) * BVH_MARGIN;
        uint wnear[3][BVH_WQ], wfar[3][BVH_WQ];   // byte plane words of each axis' near and far plane
        for (int a = 0; a < 3; ++a)
            for (int k = 0; k < BVH_WQ; ++k) {
                uint wlo = BVH_WORD(4 + 2 * a * BVH_WQ + k), whi = BVH_WORD(4 + (2 * a + 1) * BVH_WQ + k);
                wnear[a][k] = inv[a] < 0.0 ? whi : wlo;
                wfar[a][k] = inv[a] < 0.0 ? wlo : whi;
            }
        float tn[BVH_WIDTH];
        uint entered = 0u, leaves = 0u;
        BVH_CHILD_TEST(0) BVH_CHILD_TEST(1) BVH_CHILD_TEST(2) BVH_CHILD_TEST(3)
#if BVH_WIDTH == 8
        BVH_CHILD_TEST(4) BVH_CHILD_TEST(5) BVH_CHILD_TEST(6) BVH_CHILD_TEST(7)
#endif
        uint inner = entered & ~leaves;
        for (uint m = leaves; m != 0u; m &= m - 1u) {   // leaves in stored order
            int i = findLSB(m);
            int count = int((BVH_NODE_WORD(node, 4 + 6 * BVH_WQ + (i >> 2)) >> (8u * uint(i & 3))) & 0xFFu);
            if (bvh_leaf(s, int(BVH_CHILD_INDEX(node, i)), count, r.tmin, any_hit, h) && any_hit)
                return true;
        }
        float nearest_t = 3.0e38;
        int nearest = -1;
        BVH_CHILD_NEAREST(0) BVH_CHILD_NEAREST(1) BVH_CHILD_NEAREST(2) BVH_CHILD_NEAREST(3)
#if BVH_WIDTH == 8
        BVH_CHILD_NEAREST(4) BVH_CHILD_NEAREST(5) BVH_CHILD_NEAREST(6) BVH_CHILD_NEAREST(7)
#endif
        uint parent;
        int i;
        if (inner != 0u) {   // go down into one entered child, keep its siblings as one entry
            i = ordered ? nearest : findLSB(inner);
            inner &= ~(1u << uint(i));
            if (inner != 0u)
                bvh_stack[sp++] = int((node << 8) | inner);
            parent = node;
        } else {             // next sibling of the innermost group with children left
            if (sp == 0)
                break;
            uint top = uint(bvh_stack[sp - 1]);
            parent = top >> 8;
            uint m = top & 0xFFu;
            i = findLSB(m);
            m &= m - 1u;
            if (m == 0u)
                --sp;
            else
                bvh_stack[sp - 1] = int((parent << 8) | m);
        }
        node = BVH_CHILD_INDEX(parent, i);
    }
    return h.prim != BVH_MISS;
}

#undef BVH_WORD
#undef BVH_BYTE
#undef BVH_NODE_WORD
#undef BVH_CHILD_INDEX
#undef BVH_CHILD_TEST
#undef BVH_NEAR
#undef BVH_FAR
#undef BVH_MARGIN
#undef BVH_CHILD_NEAREST
#endif
