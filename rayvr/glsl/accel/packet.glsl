// Ray packets through the binary BVH: one invocation traces PACKET_RAYS rays together (the sub-rays
// of one pixel's footprint, primary.comp's MSAA trace), testing each node box once for the packet
// instead of once per ray, and each leaf triangle against every ray of the packet.
//
// Why: on the H200 a warp of coherent primary rays costs about the same per node visit whatever the
// rays (sub-rays at 16x ran at the 1x rate, 4.1 G/s on Sponza): the warp issues every box test once
// for all its lanes, so only putting several rays in one lane shares a box test between them.
//
// Exact: a packet enters a box when any of its rays could (interval bounds below), so each ray meets
// at least the triangles plain traversal tests where it could hit; each ray keeps its own closest hit
// with bvh_leaf's tie rule (equal t: the lower triangle ID), so every ray's hit is the one
// trace_closest returns (tests/test_packets.py).
//
// The packet's box test bounds, per axis, the slab distance (plane - o) * inv of its rays over their
// origins [o_lo, o_hi] and inverse directions [inv_lo, inv_hi]: both factors are rounded
// monotonically, so the bounds, taken at the interval corners, hold for the very floats bvh_slab
// computes for each ray. Where all rays share one origin (a pinhole camera) the corners halve.
// A packet whose rays go both ways along some axis (sub-rays straddling an axis plane of the scene)
// has no useful bound there: its rays are traced one by one instead (rare: a pixel's sub-rays span
// a pixel, so only pixels on the eye's axis lines, if any, have them).
#ifndef RAYVR_ACCEL_PACKET_GLSL
#define RAYVR_ACCEL_PACKET_GLSL

#include "bvh.glsl"

#if BVH_WIDTH != 2
#error "ray packets walk the binary BVH (BVH_WIDTH 2)"
#endif
#ifndef PACKET_RAYS
#define PACKET_RAYS 4
#endif

struct Packet {
    vec3 o_lo, o_hi;      // origins' bounds
    bool one_origin;      // o_lo == o_hi
    vec3 inv_lo, inv_hi;  // inverse directions' bounds (bvh_safe_inverse), one sign per axis
    bvec3 neg;            // that sign
    float tmin;           // the smallest tmin
};

// Lower bound of fl(fl(p - o) * inv) over the packet's origins and inverse directions (one sign):
// the products at the interval corners (the function is monotonic in each argument).
vec3 packet_min_t(vec3 p, Packet k) {
    vec3 a = p - k.o_hi;
    vec3 t = min(a * k.inv_lo, a * k.inv_hi);
    if (!k.one_origin) {
        vec3 b = p - k.o_lo;
        t = min(t, min(b * k.inv_lo, b * k.inv_hi));
    }
    return t;
}

vec3 packet_max_t(vec3 p, Packet k) {
    vec3 a = p - k.o_hi;
    vec3 t = max(a * k.inv_lo, a * k.inv_hi);
    if (!k.one_origin) {
        vec3 b = p - k.o_lo;
        t = max(t, max(b * k.inv_lo, b * k.inv_hi));
    }
    return t;
}

// Can any ray of the packet meet box [lo, hi] in [tmin, tmax]? tnear: a lower bound of its entry.
bool packet_slab(Packet k, vec3 lo, vec3 hi, float tmax, out float tnear) {
    vec3 t0 = packet_min_t(mix(lo, hi, k.neg), k);
    vec3 t1 = packet_max_t(mix(hi, lo, k.neg), k);
    tnear = max(max(t0.x, t0.y), max(t0.z, k.tmin));
    float tfar = min(min(t1.x, t1.y), t1.z) * 1.00000024;
    return tnear <= min(tfar, tmax);
}

// Closest hit of each ray r[i] in (r[i].tmin, r[i].tmax) into h[i], as trace_closest would give it.
void trace_packet(Ray r[PACKET_RAYS], out Hit h[PACKET_RAYS]) {
    RayShear s[PACKET_RAYS];
    bool live[PACKET_RAYS];
    const float big = 3.0e38;
    Packet k;
    k.o_lo = vec3(big);
    k.o_hi = vec3(-big);
    k.inv_lo = vec3(big);
    k.inv_hi = vec3(-big);
    k.tmin = big;
    bvec3 any_neg = bvec3(false), any_pos = bvec3(false);
    float tmax = -big;   // the packet's culling distance: its farthest closest hit so far
    for (int i = 0; i < PACKET_RAYS; ++i) {
        vec3 inv;
        live[i] = bvh_begin(r[i], h[i], s[i], inv);
        if (!live[i])
            continue;
        k.o_lo = min(k.o_lo, r[i].origin);
        k.o_hi = max(k.o_hi, r[i].origin);
        k.inv_lo = min(k.inv_lo, inv);
        k.inv_hi = max(k.inv_hi, inv);
        any_neg = bvec3(ivec3(any_neg) | ivec3(lessThan(inv, vec3(0.0))));
        any_pos = bvec3(ivec3(any_pos) | ivec3(greaterThanEqual(inv, vec3(0.0))));
        k.tmin = min(k.tmin, r[i].tmin);
        tmax = max(tmax, h[i].t);
    }
    if (k.tmin == big)   // no ray traces anything
        return;
    if (any(bvec3(ivec3(any_neg) & ivec3(any_pos)))) {   // rays going both ways on an axis: one by one
        for (int i = 0; i < PACKET_RAYS; ++i)
            if (live[i])
                trace_closest(r[i], h[i]);
        return;
    }
    k.neg = any_neg;
    k.one_origin = all(equal(k.o_lo, k.o_hi));

    BVH_LOCAL_STACK
    int sp = 0;
    int node = 0;
    while (true) {
        vec4 n0 = bvh_nodes[4 * node];
        vec4 n1 = bvh_nodes[4 * node + 1];
        vec4 n2 = bvh_nodes[4 * node + 2];
        ivec4 m = floatBitsToInt(bvh_nodes[4 * node + 3]);
        float tl, tr;
        vec3 lo, hi;
        bvh2_child_box(n0, n1, n2, 0, lo, hi);
        bool hl = packet_slab(k, lo, hi, tmax, tl);
        bvh2_child_box(n0, n1, n2, 1, lo, hi);
        bool hr = packet_slab(k, lo, hi, tmax, tr);
        for (int side = 0; side < 2; ++side) {
            bool leaf = side == 0 ? hl && m.z > 0 : hr && m.w > 0;
            if (!leaf)
                continue;
            tmax = -3.0e38;
            for (int i = 0; i < PACKET_RAYS; ++i) {
                if (live[i]) {
                    bvh_leaf(s[i], side == 0 ? m.x : m.y, side == 0 ? m.z : m.w, r[i].tmin, false, h[i]);
                    tmax = max(tmax, h[i].t);
                }
            }
            if (side == 0) {
                hl = false;
            } else {
                hr = false;
            }
        }
        hl = hl && tl <= tmax;
        hr = hr && tr <= tmax;
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
}

#endif
