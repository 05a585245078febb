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
// (rayvr/frame/passes/quadtree.py tree_uniforms sets them).
#ifndef RAYVR_SSRT_QUADTREE_GLSL
#define RAYVR_SSRT_QUADTREE_GLSL
#include "../layout.glsl"
#include "../common/camera.glsl"
#include "screen_ray.glsl"

#define QT_HIT SSRT_HIT
#define QT_OFFSCREEN SSRT_OFFSCREEN
#define QT_NEAR SSRT_NEAR
#define QT_NONE SSRT_NONE
#define QT_OCCLUDED SSRT_OCCLUDED
// QT_MAX_LEVELS, QT_PLANE_BIT, QT_FLAG_BIT, QT_HALF_MAX, QT_ON_LEAF: layout.glsl (rayvr/accel/quadtree.py)
#define QT_INF SSRT_INF

#ifndef QT_NODES_ACCESS
#define QT_NODES_ACCESS readonly
#endif
layout(std430, binding = SSBO_QUADTREE_NODES) QT_NODES_ACCESS restrict buffer QuadtreeNodes { uvec2 qt_nodes[]; };

uniform ivec4 qt_level[QT_MAX_LEVELS];  // per level: width, height, index of its first node in a layer, 0
uniform int qt_top;                     // the root's level (1 x 1)
uniform uint qt_layer_nodes;            // nodes per layer
uniform int qt_eyes = 1;                // eye layers per depth layer (tree layer = depth layer x eyes + eye)
uniform int qt_start = QT_MAX_LEVELS;   // level the walk starts on (capped at the root's): the node holding the ray's start

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

// Slab events of a plane over [ua, ub] (rayvr/accel/quadtree.py _cell): x = first u in its slab
// [z (1 - thickness), z] or -1, y = first u deeper than the slab or -1. The first point behind
// the plane is one or the other; continuing (`cont`), a deep ray may still rise into the slab.
vec2 qt_cell(QtRay r, float ua, float ub, QtNode n, vec2 c, float thickness, bool cont) {
    float uf = qt_plane_hit(r, ua, ub, n, c);
    if (uf < 0.0)
        return vec2(-1.0);
    vec3 p = r.s0 + uf * r.sd;
    float zs = n.z0 * (1.0 + n.sx * (p.x - c.x) + n.sy * (p.y - c.y));
    if (!((zs - p.z) > thickness * zs))
        return vec2(uf, -1.0);
    if (!cont)
        return vec2(-1.0, uf);
    vec3 pb = r.s0 + ub * r.sd;
    float ha = (1.0 - thickness) * zs - p.z;
    float hb = (1.0 - thickness) * n.z0 * (1.0 + n.sx * (pb.x - c.x) + n.sy * (pb.y - c.y)) - pb.z;
    return vec2(hb <= 0.0 && ha > 0.0 ? uf + (ub - uf) * ha / (ha - hb) : -1.0, uf);
}

// The pixel holding the ray's origin (on a pixel edge: the one the ray goes into), or (-1, -1)
// when the origin is off screen or before the near plane (rayvr/accel/quadtree.py _origin_cell).
ivec2 qt_origin_cell(QtRay r) {
    if (r.moved || r.u_lo != 0.0 || r.u_lo > r.u_hi)
        return ivec2(-1);
    ivec2 cell = ivec2(floor(r.s0.xy));
    cell -= ivec2(float(cell.x) == r.s0.x && r.sd.x < 0.0 ? 1 : 0, float(cell.y) == r.s0.y && r.sd.y < 0.0 ? 1 : 0);
    return clamp(cell, ivec2(0), qt_level[0].xy - 1);
}

// Does the ray's origin lie on leaf plane `n` (centre c), within its half-float slopes' 2^-11 of
// the z change across the pixel and QT_ON_LEAF of rounding (rayvr/accel/quadtree.py _starts_on)?
bool qt_starts_on(QtRay r, QtNode n, vec2 c) {
    float zs = n.z0 * (1.0 + n.sx * (r.s0.x - c.x) + n.sy * (r.s0.y - c.y));
    return abs(r.s0.z - zs) <= (QT_ON_LEAF + 0.00048828125 * 0.5 * (abs(n.sx) + abs(n.sy))) * zs;
}

// What one layer's walk found in [u_from, u_to]: the first surface hit (u_hit, pixel; u_hit =
// QT_INF if none), the first point deeper than a slab (u_occ, QT_INF if none), nodes tested,
// whether the node cap ended it.
struct QtWalk { float u_hit; ivec2 pixel; float u_occ; uint nodes; bool capped; };

// The stackless traversal of §4 of tree layer `layer` over [u_from, u_to]: plane nodes' slab
// events (qt_cell), AABB: descend when the ray dips below zmax inside, into the child holding
// its entry point (after skipping the part above zmax); on a miss the neighbour across the exit
// wall, then climb findMSB((qx ^ qx') | (qy ^ qy')) levels. Stops at the first event, or
// (`cont`) at the first surface hit only, noting the first occlusion; an AABB the ray crosses
// wholly below zmin (1 - thickness) is then one occlusion, not descended. A merged plane (k > 0)
// the ray enters already behind is descended too: a mirror ray starting on the surface may start
// behind its own pixel's proxy (up to gamma_dist off); only crossings of a proxy are hits. And the
// leaf of the origin's pixel is none to a ray that starts on it (qt_starts_on: a mirror ray off
// that surface, which rounding or the half-float slopes put behind it: the mirror saw itself).
QtWalk qt_walk(int layer, QtRay r, float u_from, float u_to, float thickness, bool cont) {
    QtWalk w = QtWalk(QT_INF, ivec2(-1), QT_INF, 0u, false);
    ivec2 size = qt_level[0].xy;
    float u = u_from;
    // Start on level qt_start in the node holding p(u) (on a pixel edge, the one the ray goes
    // into): below the root the first steps down are skipped; climbs still reach the root.
    int k = min(qt_start, qt_top);
    vec2 p0 = (r.s0 + u * r.sd).xy;
    ivec2 cell = ivec2(floor(p0));
    cell -= ivec2(float(cell.x) == p0.x && r.sd.x < 0.0 ? 1 : 0, float(cell.y) == p0.y && r.sd.y < 0.0 ? 1 : 0);
    ivec2 q = min(clamp(cell, ivec2(0), size - 1) >> k, qt_level[k].xy - 1);
    uint limit = uint(16 * (size.x + size.y) + 64);
    ivec2 own = qt_origin_cell(r);
    while (w.nodes < limit) {
        w.nodes++;
        vec4 rect = qt_rect(k, q);
        float ux = r.sd.x != 0.0 ? ((r.sd.x > 0.0 ? rect.z : rect.x) - r.s0.x) / r.sd.x : QT_INF;
        float uy = r.sd.y != 0.0 ? ((r.sd.y > 0.0 ? rect.w : rect.y) - r.s0.y) / r.sd.y : QT_INF;
        float u_exit = min(ux, uy);
        float ub = min(u_exit, u_to);
        QtNode n = qt_decode(qt_nodes[qt_index(layer, k, q)]);
        bool down = false;
        if (ub > u) {
            vec2 c = 0.5 * (rect.xy + rect.zw);
            vec3 pu = r.s0 + u * r.sd;
            if (n.plane && k > 0 && pu.z - n.z0 * (1.0 + n.sx * (pu.x - c.x) + n.sy * (pu.y - c.y)) < 0.0) {
                down = true;  // entered behind a proxy: its error, or a surface? its leaves decide
            } else if (n.plane && k == 0 && q == own && qt_starts_on(r, n, c)) {
                // the surface the ray starts on: no hit
            } else if (n.plane) {
                vec2 e = qt_cell(r, u, ub, n, c, thickness, cont);
                if (e.y >= 0.0) {
                    w.u_occ = min(w.u_occ, e.y);
                    if (!cont)
                        return w;
                }
                if (e.x >= 0.0) {
                    w.u_hit = e.x;
                    vec3 p = r.s0 + e.x * r.sd;
                    w.pixel = clamp(ivec2(floor(p.xy)), ivec2(rect.xy), ivec2(rect.zw) - 1);
                    return w;
                }
            } else {
                float za = r.s0.z + u * r.sd.z, zb = r.s0.z + ub * r.sd.z;
                if (cont && max(za, zb) < (1.0 - thickness) * n.zmin) {
                    w.u_occ = min(w.u_occ, u);  // behind every slab in the node: occluded all through
                } else if (min(za, zb) < n.zmax) {
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
        if (u_exit >= u_to)
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
    w.capped = w.nodes >= limit;
    return w;
}

// status: QT_HIT, QT_OCCLUDED (passed deeper than the last layer's slab) or how the ray ended;
// layer: the depth layer hit (-1 otherwise); pixel: the hit pixel (QT_OCCLUDED: the pixel crossed
// just before, for inpainting, or -1); point in S; nodes tested.
struct QtResult { uint status; uint nodes; ivec2 pixel; vec3 point; int layer; };

// Tree layer of depth layer `depth_layer` seen by `eye` (depth layers after each other).
int qt_tree_layer(int depth_layer, int eye) { return depth_layer * qt_eyes + eye; }

// The pixel the ray crossed just before u (the near side of an occlusion boundary), or -1.
ivec2 qt_before(QtRay r, float u) {
    if (!(u > r.u_lo) || (r.sd.x == 0.0 && r.sd.y == 0.0))
        return ivec2(-1);
    vec3 p = r.s0 + max(u - 1e-3, r.u_lo) * r.sd;
    return clamp(ivec2(floor(p.xy)), ivec2(0), qt_level[0].xy - 1);
}

// The occlusion-aware trace of §4.1 through `layers` (1 or 2) depth layers, each surface a slab
// of relative `thickness` (rayvr/accel/quadtree.py trace_layers: the rules and their reasons).
QtResult qt_trace_layers(int eye, vec3 origin, vec3 direction, int layers, float thickness) {
    QtRay r = qt_screen_ray(eye, origin, direction);
    QtResult res = QtResult(r.end, 0u, ivec2(-1), r.s0, -1);
    if (r.u_lo > r.u_hi)
        return res;
    bool two = layers > 1;
    QtWalk w = qt_walk(qt_tree_layer(0, eye), r, r.u_lo, r.u_hi, thickness, two);
    res.nodes = w.nodes;
    int layer = 0;
    if (two && w.u_occ < w.u_hit && !w.capped) {
        QtWalk w2 = qt_walk(qt_tree_layer(1, eye), r, w.u_occ, min(w.u_hit, r.u_hi), thickness, false);
        res.nodes += w2.nodes;
        if (w2.u_hit < QT_INF || w2.u_occ < QT_INF || w2.capped) {
            w = w2;
            layer = 1;
        } else {
            w.u_occ = QT_INF;
        }
    }
    if (w.u_hit < QT_INF) {
        res.status = QT_HIT;
        res.layer = layer;
        res.pixel = w.pixel;
        res.point = r.s0 + w.u_hit * r.sd;
    } else if (w.u_occ < QT_INF && !w.capped) {
        res.status = QT_OCCLUDED;
        res.pixel = qt_before(r, w.u_occ);
        res.point = r.s0 + w.u_occ * r.sd;
    } else {
        res.status = w.capped ? QT_NONE : r.end;
        res.point = r.u_hi < QT_INF ? r.s0 + r.u_hi * r.sd : r.s0;
    }
    return res;
}

// One layer as a height field: the first point behind the surface (statuses as above, never
// QT_OCCLUDED).
QtResult qt_trace(int eye, vec3 origin, vec3 direction) {
    return qt_trace_layers(eye, origin, direction, 1, QT_INF);
}

#endif
