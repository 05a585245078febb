// A ray in screen space S of one eye (x, y in pixels, GL convention; z = near / view depth), shared
// by the screen-space tracers (ssrt/quadtree.glsl, ssrt/hiz.glsl; rayvr/accel/quadtree.py
// screen_ray is its numpy mirror): the ray clipped at the near plane, projected (a straight line in
// S, z linear along it) and clipped to the image of `size` pixels. Needs common/camera.glsl.
#ifndef RAYVR_SSRT_SCREEN_RAY_GLSL
#define RAYVR_SSRT_SCREEN_RAY_GLSL
#include "../layout.glsl"  // SSRT_HIT ... SSRT_OCCLUDED, SSRT_INF: rayvr/accel/quadtree.py
#include "../common/camera.glsl"

// A ray in S: p(u) = s0 + u sd, u in pixels along the screen (|sd.xy| = 1), or u in [0, 1] with
// sd.xy = 0 for a ray along a pixel's line of sight; [u_lo, u_hi] is on screen and past the near
// plane (empty: u_lo > u_hi); `end` is the status of a ray that meets nothing there.
struct ScreenRay { vec3 s0; vec3 sd; float u_lo; float u_hi; uint end; bool moved; };

ScreenRay screen_ray(int eye, vec3 origin, vec3 direction, vec2 size) {
    ScreenRay r = ScreenRay(vec3(0.0), vec3(0.0), 0.0, -1.0, SSRT_NEAR, false);
    float n = eye_depth.x;
    vec4 t = eye_tangents[eye];
    vec2 k = size / vec2(t.y - t.x, t.w - t.z);          // pixels per tangent unit
    mat3 to_view = transpose(eye_rotation[eye]);
    vec3 o = to_view * (origin - eye_position[eye]);
    vec3 d = to_view * direction;
    float da = -o.z, dd = -d.z;                          // view depth at the origin and its rate
    float s;
    if (dd > 0.0)
        s = max(0.0, (n - da) / dd);
    else if (da >= n)
        s = 0.0;
    else
        return r;                                        // wholly in front of the near plane
    vec3 a = o + s * d;
    r.moved = s > 0.0;                                   // onto the near plane
    da = -a.z;
    r.s0 = vec3((a.xy / da - t.xz) * k, n / da);
    // Screen direction of the projected line (any sign of dd) and dz per pixel along it.
    vec2 w = (d.xy * da - a.xy * dd) * k;
    float wlen = length(w);
    vec2 mag = (abs(d.xy * da) + abs(a.xy * dd)) * k;
    r.end = dd >= 0.0 ? SSRT_NONE : SSRT_NEAR;
    float u_max;
    if (wlen <= 1e-6 * (mag.x + mag.y) || wlen == 0.0) {  // along a pixel's line of sight
        if (dd == 0.0) {
            r.end = SSRT_NONE;
            return r;
        }
        r.sd = vec3(0.0, 0.0, (dd > 0.0 ? 0.0 : 1.0) - r.s0.z);
        u_max = 1.0;
    } else {
        r.sd = vec3(w / wlen, -n * dd / wlen);
        u_max = dd == 0.0 ? SSRT_INF : ((dd > 0.0 ? 0.0 : 1.0) - r.s0.z) / r.sd.z;
    }
    float lo = 0.0, hi = u_max;
    for (int i = 0; i < 2; i++) {
        float c = r.s0[i], dc = r.sd[i];
        if (dc != 0.0) {
            float u0 = -c / dc, u1 = (size[i] - c) / dc;
            lo = max(lo, min(u0, u1));
            hi = min(hi, max(u0, u1));
        } else if (!(c >= 0.0 && c <= size[i])) {
            lo = 0.0; hi = -1.0;
        }
    }
    r.u_lo = lo;
    r.u_hi = hi;
    if (lo > hi || hi < u_max)
        r.end = SSRT_OFFSCREEN;
    return r;
}

#endif
