// Rays, hits, and the self-intersection offset shared by every ray-tracing pass.
#ifndef RAYVR_ACCEL_RAY_GLSL
#define RAYVR_ACCEL_RAY_GLSL

#include "../layout.glsl"  // BVH_MISS: rayvr/accel/gpu.py MISS

struct Ray {
    vec3 origin;
    float tmin;     // hits count only for tmin < t < tmax, t in units of |direction|
    vec3 direction; // need not be normalized; zero, NaN or inf directions never hit
    float tmax;
};

struct Hit {
    float t;
    uint prim;      // original (caller's) triangle ID, BVH_MISS when nothing was hit
    uint slot;      // reordered triangle slot inside the BVH (for bvh_triangle_* helpers)
    vec2 uv;        // barycentrics: point = (1-u-v) v0 + u v1 + v v2 (Embree's convention)
};

// Start point for a ray leaving a surface at p with geometric normal n (pointing to the side the
// ray leaves through). Wächter & Binder, Ray Tracing Gems ch. 6: far from the origin move p a fixed
// number of ulps per axis (an integer step on the float bits, so the offset scales with |p|); near the
// origin, where ulps become denormal-small, move it a small fixed distance instead.
// Compute p from the barycentrics (bvh_hit_point), not from origin + t * direction, whose error grows
// with t. The paper's 256 ulps per unit normal is 2 scene units at 1e5 from the origin, more than a
// 1-unit object there; with barycentric hit points 4 ulps already left no self-hits in 20k rays per
// case (tests/test_traversal_gpu.py spheres at 1e-3..1e5 scale, 1e5 offset), 2 ulps did not: 32 keeps
// an 8x margin.
// OFFSET_ORIGIN_BAND, OFFSET_FLOAT_SCALE, OFFSET_INT_SCALE: layout.glsl (rayvr/accel/bvh.py offset_ray)
vec3 offset_ray(vec3 p, vec3 n) {
    const float origin_band = OFFSET_ORIGIN_BAND;
    const float float_scale = OFFSET_FLOAT_SCALE;
    const float int_scale = OFFSET_INT_SCALE;
    ivec3 of_i = ivec3(int_scale * n);
    vec3 p_i = vec3(
        intBitsToFloat(floatBitsToInt(p.x) + (p.x < 0.0 ? -of_i.x : of_i.x)),
        intBitsToFloat(floatBitsToInt(p.y) + (p.y < 0.0 ? -of_i.y : of_i.y)),
        intBitsToFloat(floatBitsToInt(p.z) + (p.z < 0.0 ? -of_i.z : of_i.z)));
    return vec3(
        abs(p.x) < origin_band ? p.x + float_scale * n.x : p_i.x,
        abs(p.y) < origin_band ? p.y + float_scale * n.y : p_i.y,
        abs(p.z) < origin_band ? p.z + float_scale * n.z : p_i.z);
}

#endif
