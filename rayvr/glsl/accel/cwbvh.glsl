// Compressed 8-wide BVH (Ylitie, Karras and Laine 2017; rayvr/accel/cwbvh.py): bvh_traverse for
// bvh.glsl, with BVH_COMPRESSED 1 (layout `cwbvh`).
//   bvh_cw: 5 uvec4 (80 bytes) per node, root first: origin.xyz bits, (ex, ey, ez, imask) bytes;
//           child base (node of the first internal child), triangle base (uvec4 index of the
//           node's first triangle); 8 meta bytes; 8-byte planes q_lo.xyz, q_hi.xyz (byte s: slot s),
//           plane = origin + q * 2^(e-127). Then the triangles, 3 uvec4 each: (v0, original ID),
//           (v1, binary slot), (v2, 0), leaf by leaf.
//   meta byte of slot s: 0 empty; 24 + s | 0b00100000 internal; leaf: triangle count in unary
//           in the top 3 bits, first triangle's offset from the triangle base in the low 5 bits.
//
// The traversal keeps groups, (base, mask) pairs, as the paper does: a node group is (child base,
// visit bits << 24 | imask), bit 24 + k meaning "the internal child in slot k ^ octant was entered"
// (octant: the ray direction's sign bits, so the children come in the order the build placed them
// for this octant: accel/cwbvh.py octant_slots); a triangle group is (triangle base, one bit per
// entered triangle, bits 0..23). The current node group yields the next child; what is left of it
// goes on the stack, one entry a level (cwbvh.CwBvh.group_stack_bound). A node's triangles are
// tested right after its fetch, before its children. A popped group with no visit bits is a
// triangle group: the loop tests those too, but this traversal never postpones triangles onto the
// stack (the paper does when few lanes of a warp have triangles; GLSL 4.30 has no warp votes).
// The child test carries the ray into the node's frame as bvh_wide.glsl does (one fused
// multiply-add a plane, the bases widened by BVH_CW_MARGIN of their size), conservative, so only
// bvh_test_triangle decides hits, and they are bvh2's bit for bit.
#ifndef RAYVR_ACCEL_CWBVH_GLSL
#define RAYVR_ACCEL_CWBVH_GLSL

// BVH_CW_NODE_VEC4 (uvec4 a node), BVH_CW_MARGIN: layout.glsl (rayvr/accel/cwbvh.py)
layout(std430, binding = BVH_NODES_BINDING) readonly restrict buffer BvhCompressed { uvec4 bvh_cw[]; };
#if BVH_CW_NODE_VEC4 != 5
#error "bvh_traverse reads a node as five uvec4"
#endif

// byte i (a constant) of the 8-byte plane held in words (w0, w1)
#define BVH_CW_BYTE(w0, w1, i) float(((((i) < 4) ? (w0) : (w1)) >> (8u * uint((i) & 3))) & 0xFFu)
// No branch on an empty slot (meta 0): its box may pass, but it sets no visit bit (offset < 24) and
// adds no triangle (count 0); branch-free slots were 1-4 % faster on the GPU.
#define BVH_CW_CHILD(i) { \
        uint m = (meta[(i) >> 2] >> (8u * uint((i) & 3))) & 0xFFu; \
        { \
            vec3 t0 = vec3(BVH_CW_BYTE(near_x.x, near_x.y, i), BVH_CW_BYTE(near_y.x, near_y.y, i), \
                           BVH_CW_BYTE(near_z.x, near_z.y, i)) * step + base_near; \
            vec3 t1 = vec3(BVH_CW_BYTE(far_x.x, far_x.y, i), BVH_CW_BYTE(far_y.x, far_y.y, i), \
                           BVH_CW_BYTE(far_z.x, far_z.y, i)) * step + base_far; \
            float tn = max(max(t0.x, t0.y), max(t0.z, r.tmin)); \
            if (tn <= min(min(min(t1.x, t1.y), t1.z) * 1.00000024, bvh_reach(h.t))) { \
                uint at = m & 0x1Fu; \
                if (at >= 24u) visits |= 1u << (uint(i) ^ octant); \
                else tri_hits |= (m >> 5u) << at; \
            } \
        } \
    }

bool bvh_traverse(Ray r, bool any_hit, inout Hit h) {
    RayShear s;
    vec3 inv;
    if (!bvh_begin(r, h, s, inv))
        return false;
    BVH_LOCAL_STACK
    int sp = 0;
    uint octant = (inv.x < 0.0 ? 4u : 0u) | (inv.y < 0.0 ? 2u : 0u) | (inv.z < 0.0 ? 1u : 0u);
    uvec2 group = uvec2(0u, 1u << 24);   // the root: visit bit 0, no imask, so node base + 0
    uvec2 tris = uvec2(0u);
    while (true) {
        if ((group.y & 0xFF000000u) != 0u) {
            uint k = uint(findLSB(group.y >> 24));
            group.y &= ~(1u << (24u + k));
            if ((group.y & 0xFF000000u) != 0u) {   // siblings left: keep the group
                bvh_stack[2 * sp] = int(group.x);
                bvh_stack[2 * sp + 1] = int(group.y);
                ++sp;
            }
            uint slot = k ^ octant;
            uint node = group.x + uint(bitCount(group.y & ((1u << slot) - 1u) & 0xFFu));
            BVH_WORK(0);
            // The node's five uvec4 as five variables, each word read by a constant swizzle: NVIDIA's
            // compiler put an array of them in local memory, which made this traversal 3.5-4.4x slower
            // on the GPU (docs/design.md, cwbvh).
            int word = int(node) * BVH_CW_NODE_VEC4;
            uvec4 n0 = bvh_cw[word], n1 = bvh_cw[word + 1], n2 = bvh_cw[word + 2], n3 = bvh_cw[word + 3], n4 = bvh_cw[word + 4];
            uint e = n0.w;
            vec3 scale = uintBitsToFloat(uvec3(e & 0xFFu, (e >> 8) & 0xFFu, (e >> 16) & 0xFFu) << 23u);
            vec3 step = scale * inv;   // exact: scale is a power of two
            vec3 base = (uintBitsToFloat(n0.xyz) - r.origin) * inv;
            vec3 base_near = base - abs(base) * BVH_CW_MARGIN, base_far = base + abs(base) * BVH_CW_MARGIN;
            // the near and far plane of each axis, by the direction's sign (words 8.. lo, 14.. hi)
            uvec2 lo_x = n2.xy, lo_y = n2.zw, lo_z = n3.xy, hi_x = n3.zw, hi_y = n4.xy, hi_z = n4.zw;
            uvec2 near_x = inv.x < 0.0 ? hi_x : lo_x, far_x = inv.x < 0.0 ? lo_x : hi_x;
            uvec2 near_y = inv.y < 0.0 ? hi_y : lo_y, far_y = inv.y < 0.0 ? lo_y : hi_y;
            uvec2 near_z = inv.z < 0.0 ? hi_z : lo_z, far_z = inv.z < 0.0 ? lo_z : hi_z;
            uvec2 meta = n1.zw;
            uint visits = 0u, tri_hits = 0u;
            BVH_CW_CHILD(0) BVH_CW_CHILD(1) BVH_CW_CHILD(2) BVH_CW_CHILD(3)
            BVH_CW_CHILD(4) BVH_CW_CHILD(5) BVH_CW_CHILD(6) BVH_CW_CHILD(7)
            group = uvec2(n1.x, (visits << 24) | (e >> 24));
            tris = uvec2(n1.y, tri_hits);
        } else {   // a triangle group from the stack
            tris = group;
            group = uvec2(0u);
        }
        while (tris.y != 0u) {
            uint j = uint(findLSB(tris.y));
            tris.y &= tris.y - 1u;
            uint at = tris.x + 3u * j;
            vec4 a = uintBitsToFloat(bvh_cw[at]), b = uintBitsToFloat(bvh_cw[at + 1u]), c = uintBitsToFloat(bvh_cw[at + 2u]);
            if (bvh_test_triangle(s, floatBitsToUint(b.w), a, b, c, r.tmin, h) && any_hit)
                return true;
        }
        if ((group.y & 0xFF000000u) == 0u) {
            if (sp == 0)
                break;
            --sp;
            group = uvec2(uint(bvh_stack[2 * sp]), uint(bvh_stack[2 * sp + 1]));
        }
    }
    return h.prim != BVH_MISS;
}

#undef BVH_CW_BYTE
#undef BVH_CW_CHILD
#endif
