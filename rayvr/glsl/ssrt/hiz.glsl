// Hi-Z screen-space tracing: a hierarchical traversal of a min-max depth pyramid (the baseline
// beside DDA and the quadtree). rayvr/bench/tracers/hiz.py trace_hiz_reference is its numpy mirror, step
// for step; tests/test_hiz.py compares both with the brute-force height field.
//
//   HizResult hiz_trace(int eye, vec3 origin, vec3 direction, int start_level,
//                       int max_iterations, float thickness_factor, bool skip_origin);
//
//   eye             layer of the pyramid (and index of the camera uniforms of common/camera.glsl)
//   origin          scene-local ray origin (world - scene origin), as G-buffer positions are
//   direction       scene-local direction (any length, not zero)
//   start_level     the level the walk starts on (clamped to [0, hiz_top]); any level is correct
//   max_iterations  most cells visited; running out is HIZ_NONE
//   thickness_factor 1 / (1 + thickness) as in ssrt/dda.glsl: a pixel is the slab
//                   z in [z_s * factor, z_s]; 0 = infinite thickness (a solid height field)
//   skip_origin     start where the ray leaves the origin's pixel, as dda.glsl does (a reflection
//                   ray's origin lies on the surface its pixel shows; a flat pixel would stop it
//                   at once wherever that surface recedes); no effect on a ray moved onto the
//                   near plane. false: the brute force's semantics, the origin's pixel tested
//
// Screen space S as in dda.glsl / quadtree.glsl: x, y in pixels (GL, origin bottom-left), z = near
// / view depth. The ray is projected as quadtree.glsl does (hiz_screen_ray mirrors qt_screen_ray):
// p(u) = s0 + u sd, u in pixels along the screen. Statuses HIZ_HIT / HIZ_OFFSCREEN / HIZ_NEAR /
// HIZ_NONE have the values of DDA_* and QT_*. The origin's own pixel is tested unless skip_origin
// (the brute force tests it; DDA skips it). `pixel`/`point` of the hit, else pixel (-1, -1) and the point where the
// ray left / ended (where it stopped when out of iterations); `iterations` = cells visited.
//
// The pyramid (ssrt/hiz_build.comp): level k has ceil(W/2^k) x ceil(H/2^k) cells, each vec2(zmin,
// zmax) of its pixels' z; background pixels count in neither (a cell of background only is
// (HIZ_EMPTY, 0): no ray, z > 0, passes below 0).
//
// The walk: visit the cell at level k holding p(u); the ray's z over [u, exit] (exit = the first
// far wall) against the cell's slab [zmin * factor, zmax]. Overlap: move u to where the ray enters
// the slab and go down a level (at level 0: a hit). Miss: step to the neighbour across the wall
// that comes first (that axis only: a corner tie costs one empty visit, never a skipped cell) and
// go up a level. Cells are tracked as integers and u only moves to walls computed by one formula,
// so no position is nudged (the failure modes of float cell lookups, research notes 1.5).
#ifndef RAYVR_SSRT_HIZ_GLSL
#define RAYVR_SSRT_HIZ_GLSL
#include "../layout.glsl"
#include "../common/camera.glsl"
#include "screen_ray.glsl"

#define HIZ_HIT SSRT_HIT
#define HIZ_OFFSCREEN SSRT_OFFSCREEN
#define HIZ_NEAR SSRT_NEAR
#define HIZ_NONE SSRT_NONE
#define HIZ_MAX_LEVELS QT_MAX_LEVELS  // HIZ_EMPTY: layout.glsl (rayvr/bench/tracers/hiz.py)
#define HIZ_INF SSRT_INF

#ifndef HIZ_LEVELS_ACCESS
#define HIZ_LEVELS_ACCESS readonly
#endif
// An SSBO rather than a mipmapped texture: mips are floor(W/2^k) wide, which drops the last
// column of an odd level; ceil sizes keep every 2 x 2 reduction simple and every pixel covered.
layout(std430, binding = SSBO_HIZ_LEVELS) HIZ_LEVELS_ACCESS restrict buffer HizLevels { vec2 hiz_cells[]; };

uniform ivec4 hiz_level[HIZ_MAX_LEVELS];  // per level: width, height, index of its first cell in a layer, 0
uniform int hiz_top;                      // the 1 x 1 level
uniform uint hiz_layer_cells;             // cells per layer

uint hiz_index(int eye, int k, ivec2 q) {
    return uint(eye) * hiz_layer_cells + uint(hiz_level[k].z + q.y * hiz_level[k].x + q.x);
}

// The ray in S (ssrt/screen_ray.glsl), for this pyramid's image.
#define HizRay ScreenRay
HizRay hiz_screen_ray(int eye, vec3 origin, vec3 direction) {
    return screen_ray(eye, origin, direction, vec2(hiz_level[0].xy));
}

// u where the ray meets the wall x = c (axis 0) or y = c (axis 1); HIZ_INF for a ray parallel to
// it (no infinite reciprocal). The one formula for every wall, so a wall shared by two cells, or
// by a cell and its child, gives the same u bit for bit.
float hiz_wall(HizRay r, int axis, float c) {
    return r.sd[axis] != 0.0 ? (c - r.s0[axis]) / r.sd[axis] : HIZ_INF;
}

// The child (at level k - 1) of cell q (level k) that holds p(u): which side of each mid line,
// decided in u (the ray is past the mid line from the u where it crosses it on), so a ray that
// just stepped across a wall that is the mid line lands in the cell it stepped into.
ivec2 hiz_child(HizRay r, float u, int k, ivec2 q) {
    ivec2 c;
    for (int i = 0; i < 2; i++) {
        float mid = float((2 * q[i] + 1) << (k - 1));
        if (r.sd[i] > 0.0)
            c[i] = u >= hiz_wall(r, i, mid) ? 1 : 0;
        else if (r.sd[i] < 0.0)
            c[i] = u >= hiz_wall(r, i, mid) ? 0 : 1;
        else
            c[i] = r.s0[i] >= mid ? 1 : 0;
    }
    return min(2 * q + c, hiz_level[k - 1].xy - 1);
}

struct HizResult { uint status; uint iterations; ivec2 pixel; vec3 point; };

HizResult hiz_trace(int eye, vec3 origin, vec3 direction, int start_level, int max_iterations,
                    float thickness_factor, bool skip_origin) {
    HizRay r = hiz_screen_ray(eye, origin, direction);
    HizResult res = HizResult(r.end, 0u, ivec2(-1), r.s0);
    if (r.u_lo > r.u_hi)
        return res;
    int k = clamp(start_level, 0, hiz_top);
    float u = r.u_lo;
    if (skip_origin && !r.moved && u == 0.0) {
        // The far walls of the origin's pixel (on a pixel edge, the pixel the ray goes into).
        vec2 px = floor(r.s0.xy);
        for (int i = 0; i < 2; i++)
            if (r.sd[i] < 0.0 && r.s0[i] == px[i])
                px[i] -= 1.0;
        float ux = hiz_wall(r, 0, r.sd.x > 0.0 ? px.x + 1.0 : px.x);
        float uy = hiz_wall(r, 1, r.sd.y > 0.0 ? px.y + 1.0 : px.y);
        u = max(min(ux, uy), u);
        if (u >= r.u_hi) {                          // never leaves it: nothing tested
            res.point = r.u_hi < HIZ_INF ? r.s0 + r.u_hi * r.sd : r.s0;
            return res;
        }
    }
    // The start cell holds p(u_lo); on a cell edge, the cell the ray goes into.
    vec2 p = (r.s0 + u * r.sd).xy;
    ivec2 q = ivec2(floor(p)) >> k;
    for (int i = 0; i < 2; i++)
        if (r.sd[i] < 0.0 && p[i] == float(q[i] << k) && q[i] > 0)
            q[i]--;
    q = clamp(q, ivec2(0), hiz_level[k].xy - 1);
    bool out_of_iterations = true;
    while (res.iterations < uint(max_iterations)) {
        res.iterations++;
        ivec2 lo = q << k;
        ivec2 hi = min(lo + (1 << k), hiz_level[0].xy);
        float ux = hiz_wall(r, 0, float(r.sd.x > 0.0 ? hi.x : lo.x));
        float uy = hiz_wall(r, 1, float(r.sd.y > 0.0 ? hi.y : lo.y));
        float u_exit = max(min(ux, uy), u);
        float ub = min(u_exit, r.u_hi);
        vec2 mm = hiz_cells[hiz_index(eye, k, q)];
        float slab_lo = mm.x * thickness_factor, slab_hi = mm.y;
        float za = r.s0.z + u * r.sd.z, zb = r.s0.z + ub * r.sd.z;
        if (ub > u && min(za, zb) < slab_hi && max(za, zb) >= slab_lo) {
            // Where the ray enters the slab (it is inside it somewhere in [u, ub], so the
            // divisions happen only when it moves in z).
            float ue = u;
            if (za >= slab_hi)
                ue = (slab_hi - r.s0.z) / r.sd.z;
            else if (za < slab_lo)
                ue = (slab_lo - r.s0.z) / r.sd.z;
            u = clamp(ue, u, ub);
            if (k == 0) {
                res.status = HIZ_HIT;
                res.pixel = q;
                res.point = r.s0 + u * r.sd;
                return res;
            }
            q = hiz_child(r, u, k, q);
            k--;
            continue;
        }
        if (u_exit >= r.u_hi) {
            out_of_iterations = false;
            break;
        }
        u = u_exit;
        if (ux <= uy)
            q.x += r.sd.x > 0.0 ? 1 : -1;
        else
            q.y += r.sd.y > 0.0 ? 1 : -1;
        if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, hiz_level[k].xy))) {
            out_of_iterations = false;
            break;
        }
        if (k < hiz_top) {  // after a miss, try a coarser cell
            k++;
            q >>= 1;
        }
    }
    if (out_of_iterations) {
        res.status = HIZ_NONE;
        res.point = r.s0 + u * r.sd;
    } else {
        res.point = r.u_hi < HIZ_INF ? r.s0 + r.u_hi * r.sd : r.s0;
    }
    return res;
}

#endif
