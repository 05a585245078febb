// Search the kd-tree photon map (the paper's baseline; built on the CPU by
// accel/photon_map.build_kdtree, uploaded by frame/effects/photon/kdtree.py): the node of array range
// [lo, hi) is its median mid = (lo + hi) / 2, split along photon_extra (0..2); the near side is
// searched first, the far side only if the splitting plane is within the (shrinking) radius.
// Record 0 is a header (word 0: the photon count); the tree's array starts at record 1.
#ifndef RAYVR_PHOTON_KDTREE_GLSL
#define RAYVR_PHOTON_KDTREE_GLSL
#include "photon.glsl"

#define KD_STACK 48  // > depth of a balanced tree of 2^40 photons

layout(std430, binding = SSBO_PHOTON_KDTREE) readonly restrict buffer PhotonKdTree { Photon photon_kdtree[]; };

float photon_search_r2();
void photon_visit(uint index, Photon p, float d2);

void kdtree_search(vec3 q) {
    uvec2 stack[KD_STACK];
    int sp = 0;
    stack[sp++] = uvec2(0u, floatBitsToUint(photon_kdtree[0].position_normal.x));
    while (sp > 0) {
        uvec2 range = stack[--sp];
        if (range.x >= range.y) continue;
        uint mid = (range.x + range.y) >> 1;
        Photon p = photon_kdtree[mid + 1u];
        vec3 d = photon_position(p) - q;
        float d2 = dot(d, d);
        if (d2 <= photon_search_r2()) photon_visit(mid, p, d2);
        uint axis = photon_extra(p);
        float delta = q[axis] - photon_position(p)[axis];
        uvec2 lo = uvec2(range.x, mid), hi = uvec2(mid + 1u, range.y);
        if (delta * delta <= photon_search_r2() && sp < KD_STACK) stack[sp++] = delta < 0.0 ? hi : lo;
        if (sp < KD_STACK) stack[sp++] = delta < 0.0 ? lo : hi;
    }
}

#endif
