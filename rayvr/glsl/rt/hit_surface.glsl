// The surface a ray hit, in the G-buffer's terms (common/surface.glsl), so secondary hits are
// shaded exactly like G-buffer pixels: common/triangle_surface.glsl, shared with the G-buffer
// resolve, with the BVH's barycentrics and the finest texture level (secondary rays carry no ray
// differentials yet).
#ifndef RAYVR_RT_HIT_SURFACE_GLSL
#define RAYVR_RT_HIT_SURFACE_GLSL
#include "../common/gbuffer.glsl"
#include "../common/triangle_surface.glsl"
#include "../accel/bvh.glsl"

// The point of triangle `tri` nearest p (p projected on its plane), from barycentrics as
// bvh_hit_point computes a hit: the accuracy offset_ray (accel/ray.glsl) counts on. The G-buffer's
// point is eye + t * dir, off the plane by rounding errors of the eye's distance (~1e-6 five units
// away), where offset_ray lifts a point only a few ulps of each coordinate (~1e-7 at |z| ~ 0.05):
// rays started there hit their own surface (shadow rays: dark speckles).
vec3 point_on_triangle(uint tri, vec3 p) {
    TriangleVerts tv = scene_triangle(tri);
    vec3 e1 = tv.p[1] - tv.p[0], e2 = tv.p[2] - tv.p[0], n = triangle_normal(tv), q = p - tv.p[0];
    vec2 b = vec2(dot(cross(q, e2), n), dot(cross(e1, q), n)) / dot(n, n);
    return tv.p[0] + b.x * e1 + b.y * e2;
}

// ng: unit geometric normal, turned to face the incoming ray (the side secondary rays leave from).
Surface surface_at_hit(Hit h, vec3 dir, out vec3 ng) {
    TriangleVerts tv = scene_triangle(h.prim);
    ng = normalize(triangle_normal(tv));
    Surface s = triangle_surface(h.prim, tv, vec3(1.0 - h.uv.x - h.uv.y, h.uv.x, h.uv.y), ng, dir, 0.0);
    if (dot(ng, dir) > 0.0) ng = -ng;
    // From barycentrics on the scene triangle (the BVH's copy holds the same vertices in the same
    // order, so this equals bvh_hit_point): what offset_ray expects; screen-space hits have no slot.
    s.position = tv.p[0] + h.uv.x * (tv.p[1] - tv.p[0]) + h.uv.y * (tv.p[2] - tv.p[0]);
    s.view_depth = h.t;
    return s;
}

#endif
