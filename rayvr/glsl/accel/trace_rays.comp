#version 430
// Trace a batch of rays for tests and benchmarks (rayvr/accel/gpu.py: RayTracer).
// TRACE_MODE 0: closest hit; 1: any hit; 2: closest hit, then a mirror-reflected ray from
// offset_ray(hit, n); 3: closest hit, then the same direction continued from offset_ray(hit, -n).
// Modes 2 and 3 report the second ray's hit (self-intersection tests).
// With TILE_ENTRIES_BINDING (tile frustum culling), the first ray starts from its tile's entry list.
// With BVH_COUNT_WORK, each ray's traversal work (bvh.glsl bvh_work) goes to work[] at WORK_BINDING.
#ifndef TRACE_MODE
#define TRACE_MODE 0
#endif
#ifndef RAYS_BINDING
#define RAYS_BINDING 2
#endif
#ifndef HITS_BINDING
#define HITS_BINDING 3
#endif
#ifndef OFFSET_RAYS
#define OFFSET_RAYS 1
#endif
#include "../layout.glsl"
#define LOCAL_SIZE TRACE_RAYS_LOCAL  // rayvr/accel/gpu.py dispatches by it
layout(local_size_x = LOCAL_SIZE) in;

#include "bvh.glsl"

layout(std430, binding = RAYS_BINDING) readonly restrict buffer Rays { vec4 rays[]; };  // (o, tmin), (d, tmax)
layout(std430, binding = HITS_BINDING) writeonly restrict buffer Hits { uvec4 hits[]; }; // prim, t, u, v bits

#if BVH_COUNT_WORK
layout(std430, binding = WORK_BINDING) writeonly restrict buffer Work { uvec4 work[]; };
#define STORE_WORK work[i] = uvec4(bvh_work, 0u)
#else
#define STORE_WORK
#endif

uniform uint ray_count;

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * LOCAL_SIZE;
    if (i >= ray_count)
        return;
    vec4 a = rays[2 * i];
    vec4 b = rays[2 * i + 1];
    Ray r = Ray(a.xyz, a.w, b.xyz, b.w);
#if TRACE_MODE == 1
#ifdef TILE_ENTRIES_BINDING
    bool occluded = trace_any_tile(r, i);
#else
    bool occluded = trace_any(r);
#endif
    hits[i] = uvec4(occluded ? 1u : 0u, 0u, 0u, 0u);
    STORE_WORK;
#else
    Hit h;
#ifdef TILE_ENTRIES_BINDING
    trace_closest_tile(r, i, h);
#else
    trace_closest(r, h);
#endif
#if TRACE_MODE >= 2
    if (h.prim != BVH_MISS) {
        vec3 n = bvh_geometric_normal(h.slot);
        n = dot(n, r.direction) > 0.0 ? -n : n;     // n faces the incoming ray
        vec3 p = bvh_hit_point(h);
        Ray r2;
#if TRACE_MODE == 2
        r2.direction = reflect(r.direction, n);
#else
        r2.direction = r.direction;
        n = -n;
#endif
#if OFFSET_RAYS
        r2.origin = offset_ray(p, n);
#else
        r2.origin = p;
#endif
        r2.tmin = 0.0;
        r2.tmax = 3.0e38;
        trace_closest(r2, h);
    }
#endif
    hits[i] = uvec4(h.prim, floatBitsToUint(h.t), floatBitsToUint(h.uv.x), floatBitsToUint(h.uv.y));
    STORE_WORK;
#endif
}
