// BVH traversal: trace_closest() and trace_any(), over the layout BVH_WIDTH picks (GpuBvh.defines):
//   2: the child-pair binary BVH of rayvr/accel/bvh.py (bvh2.glsl), the reference layout;
//   4, 8: the wide BVHs with quantized child boxes of rayvr/accel/wide.py (bvh_wide.glsl);
//   8 with BVH_COMPRESSED 1: the compressed 8-wide BVH of rayvr/accel/cwbvh.py (cwbvh.glsl).
// One traversal body per layout, shared by every ray kind (primary, shadow, reflection, glossy).
//
// Buffers (std430, bound by GpuBvh.bind(base) at base and base + 1; pass GpuBvh.defines(base)):
//   nodes:     the layout's nodes (see its file), root first.
//   bvh_tris:  3 vec4 per reordered triangle: (v0, original id bits), (v1, 0), (v2, 0); every
//              layout's leaves are ranges of these slots.
#ifndef RAYVR_ACCEL_BVH_GLSL
#define RAYVR_ACCEL_BVH_GLSL

#include "../layout.glsl"
#include "ray.glsl"
#include "triangle.glsl"

// Defaults of GpuBvh.defines (rayvr/accel/gpu.py layout_defines), which every pass sets.
#ifndef BVH_NODES_BINDING
#define BVH_NODES_BINDING SSBO_BVH_NODES
#endif
#ifndef BVH_TRIS_BINDING
#define BVH_TRIS_BINDING SSBO_BVH_TRIANGLES
#endif
#ifndef BVH_STACK_SIZE
#define BVH_STACK_SIZE BVH_BINARY_STACK_SIZE   // >= the build's max_depth, and the wide layouts' stack bound
#endif
#ifndef BVH_WIDTH
#define BVH_WIDTH 2
#endif
#ifndef BVH_COMPRESSED
#define BVH_COMPRESSED 0
#endif

#ifndef BVH_GLOBAL_STACK
#define BVH_GLOBAL_STACK 1
#endif
#if BVH_GLOBAL_STACK
// One traversal stack per invocation at file scope, shared by every inlined call site of
// bvh_traverse: a shader that traces from several places would otherwise hold one local-memory
// array per site. Measured on the GPU (2x1440x1600, `bench rays` views, variants not kept): a
// 32-entry stack in shared memory, nearer-child-first leaves, and pushing entry distances to skip
// popped nodes beyond the hit were each slower in the wavefront effect kernels (Sponza rt_shadows
// 1.17 ms with this traversal, 1.4-3.0 ms with those).
int bvh_stack[BVH_STACK_SIZE];
#define BVH_LOCAL_STACK
#else
#define BVH_LOCAL_STACK int bvh_stack[BVH_STACK_SIZE];   // one per traversal body
#endif

layout(std430, binding = BVH_TRIS_BINDING) readonly restrict buffer BvhTriangles { vec4 bvh_tris[]; };

// BVH_COUNT_WORK (tests, benchmarks: accel/gpu.py RayTracer.trace(work=)): the invocation's traversal
// work, counted by the binary and compressed layouts: x nodes fetched by walks, y tile entry boxes tested, z
// ray-triangle tests. Counts depend on the BVH and the rays, not the device.
#ifndef BVH_COUNT_WORK
#define BVH_COUNT_WORK 0
#endif
#if BVH_COUNT_WORK
uvec3 bvh_work = uvec3(0u);
#define BVH_WORK(k) bvh_work[k] += 1u
#else
#define BVH_WORK(k)
#endif

// Zero, NaN or infinite directions and empty [tmin, tmax] intervals trace nothing.
bool bvh_ray_valid(Ray r) {
    vec3 d = r.direction;
    return !any(isnan(d)) && !any(isinf(d)) && any(notEqual(d, vec3(0.0))) && r.tmax > r.tmin;
}

// 1/d, with zero components (axis-parallel rays) replaced by a large finite value of the same sign:
// (plane - origin) * inv then never computes 0 * inf = NaN, and the slab of a ray lying in a box face
// still counts as overlapping. Exactness does not matter here: only the triangle test decides hits.
vec3 bvh_safe_inverse(vec3 d) {
    const float tiny = BVH_SAFE_INVERSE_TINY;  // rayvr/accel/bvh.py safe_inverse
    vec3 sgn = mix(vec3(1.0), vec3(-1.0), lessThan(d, vec3(0.0)));
    return 1.0 / mix(d, sgn * tiny, lessThan(abs(d), vec3(tiny)));
}

// How far beyond the closest hit so far t a box may start and still be entered (BVH_HIT_REACH:
// rayvr/accel/bvh.py HIT_REACH): a closer hit in a box whose computed entry rounds past t is found
// whatever the order of the walk, so every layout and order returns the same hit.
float bvh_reach(float t) {
    return t * BVH_HIT_REACH;
}

// Slab test with the near/far plane of each axis picked by the direction's sign (an inverted empty
// box then never overlaps). far is widened by 1 + 2 gamma(3) (Ize 2013) so float rounding cannot
// cull a box that the ray grazes; tmax (the closest hit so far) by bvh_reach.
bool bvh_slab(vec3 o, vec3 inv, vec3 lo, vec3 hi, float tmin, float tmax, out float tnear) {
    bvec3 neg = lessThan(inv, vec3(0.0));
    vec3 t0 = (mix(lo, hi, neg) - o) * inv;
    vec3 t1 = (mix(hi, lo, neg) - o) * inv;
    tnear = max(max(t0.x, t0.y), max(t0.z, tmin));
    float tfar = min(min(t1.x, t1.y), t1.z) * 1.00000024;
    return tnear <= min(tfar, bvh_reach(tmax));
}

// Start of every layout's traversal: h = a miss at tmax; false for a ray that traces nothing.
bool bvh_begin(Ray r, out Hit h, out RayShear s, out vec3 inv) {
    h.t = r.tmax;
    h.prim = BVH_MISS;
    h.slot = BVH_MISS;
    h.uv = vec2(0.0);
    if (!bvh_ray_valid(r))
        return false;
    s = ray_shear(r);
    inv = bvh_safe_inverse(r.direction);
    return true;
}

// Test the triangle in BVH slot `slot` (its three vec4s a, b, c; a.w: the original ID bits),
// shrinking h.t on a closer hit. A hit at exactly h.t (a ray through an edge two triangles share)
// goes to the lower triangle ID, so every layout, the tile-culled traversal and the tile triangle
// lists (rt/primary.comp), which meet the two in different orders, report the same one.
bool bvh_test_triangle(RayShear s, uint slot, vec4 a, vec4 b, vec4 c, float tmin, inout Hit h) {
    BVH_WORK(2);
    float t;
    vec2 uv;
    // with a hit so far, admit t == h.t: the next float up is the open bound
    float tmax = h.prim == BVH_MISS ? h.t : uintBitsToFloat(floatBitsToUint(h.t) + 1u);
    if (intersect_triangle(s, a.xyz, b.xyz, c.xyz, tmin, tmax, t, uv)
        && (t < h.t || floatBitsToUint(a.w) < h.prim)) {
        h.t = t;
        h.uv = uv;
        h.slot = slot;
        h.prim = floatBitsToUint(a.w);
        return true;
    }
    return false;
}

// Test the triangles of one leaf (bvh_test_triangle); with any_hit, stop at the first hit.
bool bvh_leaf(RayShear s, int first, int count, float tmin, bool any_hit, inout Hit h) {
    bool found = false;
    for (int i = first; i < first + count; ++i) {
        if (bvh_test_triangle(s, uint(i), bvh_tris[3 * i], bvh_tris[3 * i + 1], bvh_tris[3 * i + 2], tmin, h)) {
            found = true;
            if (any_hit)
                return true;
        }
    }
    return found;
}

#if BVH_WIDTH == 2
#include "bvh2.glsl"
#elif BVH_COMPRESSED
#include "cwbvh.glsl"
#else
#include "bvh_wide.glsl"
#endif

// Closest hit in (tmin, tmax); h.prim = BVH_MISS and h.t = tmax on a miss.
bool trace_closest(Ray r, out Hit h) {
    return bvh_traverse(r, false, h);
}

// Anything in (tmin, tmax)? Stops at the first hit (shadow rays).
bool trace_any(Ray r) {
    Hit h;
    return bvh_traverse(r, true, h);
}

// Vertex k (0..2) of the triangle in BVH slot `slot` (Hit.slot).
vec3 bvh_triangle_vertex(uint slot, int k) {
    return bvh_tris[3 * int(slot) + k].xyz;
}

// Unit geometric normal, wound v0 -> v1 -> v2 (right-handed).
vec3 bvh_geometric_normal(uint slot) {
    vec3 a = bvh_triangle_vertex(slot, 0);
    return normalize(cross(bvh_triangle_vertex(slot, 1) - a, bvh_triangle_vertex(slot, 2) - a));
}

// Hit point from barycentrics: more accurate than origin + t * direction (see offset_ray).
vec3 bvh_hit_point(Hit h) {
    vec3 a = bvh_triangle_vertex(h.slot, 0);
    vec3 b = bvh_triangle_vertex(h.slot, 1);
    vec3 c = bvh_triangle_vertex(h.slot, 2);
    return a + h.uv.x * (b - a) + h.uv.y * (c - a);
}

#endif
