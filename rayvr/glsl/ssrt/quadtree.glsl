// Widmer et al. 2015 screen-space quadtree: node decoding and the stackless traversal (§4) of one
// eye layer as a height field. rayvr/accel/quadtree.py is its numpy mirror, step for step, and its
// docstring gives the node format and the build; tests/test_quadtree.py compares the two and the
// brute-force reference.
//
//   QtResult qt_trace(int eye, vec3 origin, vec3 direction);
//
//   eye        layer of the tree (and index of the camera uniforms of common/camera.glsl)
//   origin     scene-local ray origin (world - scene origin), as G-buffer positions are
//   direction  scene-local direction (any length, not zero)
//
// Screen space S: x, y in pixels (GL: origin bottom-left, centres at +0.5), z = near / view depth.
// The ray is clipped at the near plane, projected (a straight line in S, z linear along it) and
// clipped to the image. Result: status QT_HIT (first point behind a surface), QT_OFFSCREEN (left
// the image), QT_NEAR (reached the near plane or lies in front of it), QT_NONE (reached infinity on
// screen); `pixel` and `point` (in S) of the hit, else pixel (-1, -1) and the point where the ray
// left / ended; `nodes` = nodes tested.
//
// Reads: the camera uniforms (eye_position, eye_rotation, eye_tangents, eye_depth.x = near), the
// nodes at SSBO_QUADTREE_NODES (layer after layer, levels leaves first), and the uniforms below
// (rayvr/passes/quadtree.py tree_uniforms sets them).
#ifndef RAYVR_SSRT_QUADTREE_GLSL
#define RAYVR_SSRT_QUADTREE_GLSL
#include "../layout.glsl"
#include "../common/camera.glsl"
#include "screen_ray.glsl"

#define QT_HIT SSRT_HIT
#define QT_OFFSCREEN SSRT_OFFSCREEN
#define QT_NEAR SSRT_NEAR
#define QT_NONE SSRT_NONE
#define QT_MAX_LEVELS 16
#define QT_PLANE_BIT 0x80000000u
#define QT_FLAG_BIT 1u
#define QT_HALF_MAX 65504.0
#define QT_INF SSRT_INF

#ifndef QT_NODES_ACCESS
#define QT_NODES_ACCESS readonly
#endif
layout(std430, binding = SSBO_QUADTREE_NODES) QT_NODES_ACCESS restrict buffer QuadtreeNodes { uvec2 qt_nodes[]; };

uniform ivec4 qt_level[QT_MAX_LEVELS];  // per level: width, height, index of its first node in a layer, 0
uniform int qt_top;                     // the root's level (1 x 1)
uniform uint qt_layer_nodes;            // nodes per layer

uint qt_index(int eye, int k, ivec2 q) {
    return uint(eye) * qt_layer_nodes + uint(qt_level[k].z + q.y * qt_level[k].x + q.x);
}

struct QtNode {
    bool plane;
    bool flag;        // near a depth discontinuity
    float z0, sx, sy;  // plane: z at the rectangle's centre, slopes relative to z0 per pixel
    float zmin, zmax;  // AABB bounds
};

QtNode qt_decode(uvec2 w) {
    QtNode n;
    n.plane = (w.x & QT_PLANE_BIT) != 0u;
    n.flag = (w.x & QT_FLAG_BIT) != 0u;
    float v0 = uintBitsToFloat(w.x & ~QT_FLAG_BIT);
    vec2 s = unpackHalf2x16(w.y);
    n.z0 = n.plane ? -v0 : 0.0;
    n.sx = n.plane ? s.x : 0.0;
    n.sy = n.plane ? s.y : 0.0;
    n.zmin = n.plane ? 0.0 : v0;
    n.zmax = n.plane ? 0.0 : uintBitsToFloat(w.y);
    return n;
}

uvec2 qt_encode_plane(float z0, float sx, float sy, bool flag) {
    uint w0 = (floatBitsToUint(-abs(z0)) & ~QT_FLAG_BIT) | (flag ? QT_FLAG_BIT : 0u);
    return uvec2(w0, packHalf2x16(clamp(vec2(sx, sy), -QT_HALF_MAX, QT_HALF_MAX)));
}

uvec2 qt_encode_aabb(float zmin, float zmax, bool flag) {
    uint w0 = (floatBitsToUint(max(zmin, 0.0)) & ~QT_FLAG_BIT) | (flag ? QT_FLAG_BIT : 0u);
    return uvec2(w0, floatBitsToUint(max(zmax, 0.0)));
}

// Level k's node rectangle in pixels: (x0, y0, x1, y1), clipped to the image.
vec4 qt_rect(int k, ivec2 q) {
    ivec2 lo = q << k;
    ivec2 hi = min(lo + (1 << k), qt_level[0].xy);
    return vec4(lo, hi);
}

// The ray in S (ssrt/screen_ray.glsl), for this tree's image.
#define QtRay ScreenRay
QtRay qt_screen_ray(int eye, vec3 origin, vec3 direction) {
    return screen_ray(eye, origin, direction, vec2(qt_level[0].xy));
}

// First u in [ua, ub] where the ray is behind the plane (z_ray - z_plane is linear in u), or -1.
float qt_plane_hit(QtRay r, float ua, float ub, QtNode n, vec2 c) {
    vec3 pa = r.s0 + ua * r.sd, pb = r.s0 + ub * r.sd;
    float da = pa.z - n.z0 * (1.0 + n.sx * (pa.x - c.x) + n.sy * (pa.y - c.y));
    float db = pb.z - n.z0 * (1.0 + n.sx * (pb.x - c.x) + n.sy * (pb.y - c.y));
    if (da < 0.0)
        return ua;
    if (db < 0.0)
        return ua + (ub - ua) * da / (da - db);
    return -1.0;
}

struct QtResult { uint status; uint nodes; ivec2 pixel; vec3 point; };

QtResult qt_trace(int eye, vec3 origin, vec3 direction) {
    QtRay r = qt_screen_ray(eye, origin, direction);
    QtResult res;
    res.status = r.end; res.nodes = 0u; res.pixel = ivec2(-1); res.point = r.s0;
    if (r.u_lo > r.u_hi)
        return res;
    ivec2 size = qt_level[0].xy;
    int k = qt_top;
    ivec2 q = ivec2(0);
    float u = r.u_lo;
    uint limit = uint(16 * (size.x + size.y) + 64);
    bool hit = false;
    while (res.nodes < limit) {
        res.nodes++;
        vec4 rect = qt_rect(k, q);
        float ux = r.sd.x != 0.0 ? ((r.sd.x > 0.0 ? rect.z : rect.x) - r.s0.x) / r.sd.x : QT_INF;
        float uy = r.sd.y != 0.0 ? ((r.sd.y > 0.0 ? rect.w : rect.y) - r.s0.y) / r.sd.y : QT_INF;
        float u_exit = min(ux, uy);
        float ub = min(u_exit, r.u_hi);
        QtNode n = qt_decode(qt_nodes[qt_index(eye, k, q)]);
        bool down = false;
        if (ub > u) {
            if (n.plane) {
                float uh = qt_plane_hit(r, u, ub, n, 0.5 * (rect.xy + rect.zw));
                if (uh >= 0.0) {
                    res.status = QT_HIT;
                    res.point = r.s0 + uh * r.sd;
                    res.pixel = clamp(ivec2(floor(res.point.xy)), ivec2(rect.xy), ivec2(rect.zw) - 1);
                    return res;
                }
            } else {
                float za = r.s0.z + u * r.sd.z, zb = r.s0.z + ub * r.sd.z;
                if (min(za, zb) < n.zmax) {
                    if (za >= n.zmax)      // skip the part of the node the ray crosses above zmax
                        u = max(u, min(ub, (n.zmax - r.s0.z) / r.sd.z));
                    down = k > 0;
                }
            }
        }
        if (down) {
            // The child holding p(u); on a mid line, the one the ray goes into.
            vec2 p = (r.s0 + u * r.sd).xy;
            k--;
            int half_size = 1 << k;
            vec2 mid = rect.xy + float(half_size);
            ivec2 c = ivec2(p.x > mid.x || (p.x == mid.x && r.sd.x >= 0.0) ? 1 : 0,
                            p.y > mid.y || (p.y == mid.y && r.sd.y >= 0.0) ? 1 : 0);
            q = min(2 * q + c, qt_level[k].xy - 1);
            continue;
        }
        if (u_exit >= r.u_hi)
            break;
        u = u_exit;
        ivec2 step = ivec2(ux <= uy ? (r.sd.x > 0.0 ? 1 : -1) : 0, uy <= ux ? (r.sd.y > 0.0 ? 1 : -1) : 0);
        ivec2 nq = q + step;
        if (any(lessThan(nq, ivec2(0))) || any(greaterThanEqual(nq, qt_level[k].xy)))
            break;
        // Climb to the largest node that starts at the successor: below the last common ancestor.
        // findMSB(0) = -1 (no move, cannot happen here) is kept on this level.
        uvec2 diff = uvec2(q ^ nq);
        int up = min(max(findMSB(diff.x | diff.y), 0), qt_top - k);
        k += up;
        q = nq >> up;
    }
    if (res.nodes >= limit)
        res.status = QT_NONE;
    res.point = r.u_hi < QT_INF ? r.s0 + r.u_hi * r.sd : r.s0;
    return res;
}

#endif
