#version 430
// The lean kernels of the wavefront effect passes (rt/wave.glsl): nothing but traversal, so they
// keep the batch tracer's registers and occupancy while the shading lives in rt/wave_shade.comp.
//   WAVE_STAGE 0  prep: dispatch sizes of this batch from the effect's pixel count (one thread)
//   WAVE_STAGE 1  closest: each active path's ray -> its hit
//   WAVE_STAGE 2  shadow: each item's stored shadow rays, any hit; unoccluded contributions are
//                 added to its radiance; with WAVE_FINISH the pixel's colour is written as well
//                 (one path per pixel, last event)
// Stages 1 and 2 take their rays through rt/wave_fetch.glsl: one per invocation, or fetched by
// persistent threads (WAVE_PERSISTENT), in the sorted order (WAVE_RAY_ORDER) or the paths' own.
#ifndef WAVE_STAGE
#define WAVE_STAGE 1
#endif
#ifndef RT_SLOT
#define RT_SLOT 0
#endif
#include "wave.glsl"
#if WAVE_STAGE == 0
layout(local_size_x = 1) in;
uvec4 dispatch_of(uint n) {
    uint groups = (n + uint(RT_LOCAL_SIZE) - 1u) / uint(RT_LOCAL_SIZE);
    uint gx = min(groups, RT_MAX_GROUPS_X);
    uint gy = gx == 0u ? 1u : (groups + gx - 1u) / gx;
    return uvec4(gx, gy, 1u, n);
}
void main() {
    uint total = rt_args[RT_SLOT].w;
    uint n = total > wave_batch_base ? min(total - wave_batch_base, wave_capacity / wave_paths_per_pixel) : 0u;
    wave_args[0] = dispatch_of(n);
    wave_args[1] = dispatch_of(n * wave_paths_per_pixel);
#if WAVE_PERSISTENT
    for (uint s = 0u; s < wave_fetch_slots; ++s) wave_fetch_counters[s] = 0u;
#endif
}
#else
layout(local_size_x = RT_LOCAL_SIZE) in;
#include "../accel/bvh.glsl"
#include "wave_fetch.glsl"
#if WAVE_STAGE == 1
#ifndef SSR_TRACE
#define SSR_TRACE 0
#endif
#if SSR_TRACE
#include "../ssrt/quadtree.glsl"
#include "../common/gbuffer.glsl"
#include "../common/scene.glsl"

#if QT_DEPTH_LAYERS > 1
layout(binding = UNIT_LAYER2_TRIANGLE) uniform usampler2DArray layer2_triangle;  // frame/passes/second_layer.py
#endif

// The path's ray through the quadtree of the eye that sees its pixel, over the material's
// `layers` depth layers with slabs of its `thickness` (qt_trace_layers: a ray that passed deeper
// than the last layer's slab is QT_OCCLUDED). On a hit the triangle the hit layer shows at the
// hit pixel, and the ray's exact crossing of that triangle's plane as barycentrics (as the
// G-buffer resolve does). An occluded ray of a material without `fallback` is inpainted: the
// G-buffer's own point of the pixel just before the occlusion. False when the screen cannot
// answer. `mi`: the pixel's material.
bool screen_space_hit(uint p, vec3 o, vec3 d, out uint tri, out vec2 uv, out uint mi) {
    ivec3 px = wave_pixel(p % wave_args[0].w);
    mi = texelFetch(gb_material, px, 0).x;
    tri = NO_HIT;
    uv = vec2(0.0);
    QtResult r = qt_trace_layers(px.z, o, d, material_param_int(mi, PARAM_LAYERS), material_param_float(mi, PARAM_THICKNESS));
    ivec3 at = ivec3(r.pixel, px.z);
    vec3 dir = d;
    if (r.status == QT_OCCLUDED && material_param_int(mi, PARAM_FALLBACK) == 0 && r.pixel.x >= 0) {
        vec3 target = texelFetch(gb_position, at, 0).xyz;  // inpainting: the near side's own surface
        dir = target - o;
    } else if (r.status != QT_HIT) {
        return false;
    }
#if QT_DEPTH_LAYERS > 1
    tri = r.layer == 1 ? texelFetch(layer2_triangle, at, 0).x : texelFetch(gb_triangle, at, 0).x;
#else
    tri = texelFetch(gb_triangle, at, 0).x;
#endif
    if (tri == NO_HIT) return false;
    TriangleVerts tv = scene_triangle(tri);
    vec3 e1 = tv.p[1] - tv.p[0], e2 = tv.p[2] - tv.p[0], ng = triangle_normal(tv);
    float den = dot(dir, ng);
    if (abs(den) <= 1e-12 * length(ng) * length(dir)) return false;
    vec3 q = o + (dot(tv.p[0] - o, ng) / den) * dir - tv.p[0];
    float inv = 1.0 / dot(ng, ng);
    uv = clamp(vec2(dot(cross(q, e2), ng), dot(cross(e1, q), ng)) * inv, 0.0, 1.0);
    if (uv.x + uv.y > 1.0) uv /= uv.x + uv.y;
    return true;
}
#endif
uint traced_rays = 0u;  // this invocation's rays (wave_rays, while counting)

void trace_path(uint p) {
    vec4 o = wave_paths[p].origin;
    vec4 d = wave_paths[p].direction;
    if (d.w < 0.0) {
        wave_paths[p].hit = uvec4(WAVE_IDLE, BVH_MISS, 0u, 0u);
        return;
    }
    traced_rays += 1u;
#if SSR_TRACE
    uint tri, mi;
    vec2 uv;
    if (screen_space_hit(p, o.xyz, d.xyz, tri, uv, mi)) {
        wave_paths[p].hit = uvec4(0u, tri, floatBitsToUint(uv.x), floatBitsToUint(uv.y));  // slot unused
        return;
    }
    if (material_param_int(mi, PARAM_FALLBACK) == 0) {  // no BVH fallback: the background
        wave_paths[p].hit = uvec4(BVH_MISS, BVH_MISS, 0u, 0u);
        return;
    }
#endif
    Hit h;
    trace_closest(Ray(o.xyz, o.w, d.xyz, d.w), h);
    wave_paths[p].hit = uvec4(h.slot, h.prim, floatBitsToUint(h.uv.x), floatBitsToUint(h.uv.y));
}
void main() {
    WAVE_FOR_EACH_RAY(k, wave_args[1].w) trace_path(wave_ray(k));
    COUNT_RAYS(0, traced_rays);
}
#else
#ifdef WAVE_FINISH
layout(rgba16f, binding = IMAGE_HDR) uniform writeonly image2DArray hdr_out;
#endif
uniform uint wave_items;  // 0: the batch's pixels, 1: its paths (wave_args index)
uint traced_rays = 0u;  // this invocation's shadow rays (wave_rays, while counting)

// ADAPTIVE_SHADOWS 0: every slot traced in one plain loop, the kernel the pass takes where no
// light's run can be longer than its probes (no rect light, or shadow_probes 0 or at least the
// slots): the adaptive loop would trace the same rays, with more code and registers.
#ifndef ADAPTIVE_SHADOWS
#define ADAPTIVE_SHADOWS 1
#endif
#if ADAPTIVE_SHADOWS
uniform int shadow_probes;  // adaptive area-light shadows (frame/passes/trace_effect.py SHADOW_PROBES)

// Slot k of a run of m is one of its `probes` probes: probe j sits at (j * m) / probes.
bool is_probe(uint k, uint m, uint probes) {
    uint j = (k * probes + probes - 1u) / m;  // the first probe at or after k
    return j < probes && (j * m) / probes == k;
}

// One light's run of m shadow rays (slots [k0, k0 + m), light.w its index), adaptively: with more
// than shadow_probes of them, that many or a quarter of the run, whichever is more (4 points of 64
// agree wrongly too often: the room's mean error against numpy doubled), spread over the run (the
// lattice's stratified points: the run's order is the light's lattice order) are traced first; when
// they agree, the others take their visibility untraced (all lit: the run's whole sum; all blocked:
// nothing), else the others are traced too. Exact where the light is wholly seen or wholly hidden;
// in a penumbra all probes agree only when it covers less of the light than the gaps between them:
// the bias lies there (tests/test_adaptive_shadows.py bounds it against every ray traced).
// One loop of two sweeps with one trace call in it: each call site of the traversal costs the
// kernel registers and code.
vec3 adaptive_run(uint q, uint k0, uint m) {
    uint probes = max(uint(shadow_probes), (m + 3u) / 4u);
    bool adaptive = shadow_probes > 0 && m > probes;
    vec3 sum = vec3(0.0), all_of_run = vec3(0.0);
    uint seen = 0u;
    for (uint step = 0u; step < 2u * m; ++step) {
        bool rest = step >= m;  // the second sweep: the slots the probes left
        uint k = rest ? step - m : step;
        if (step == m) {  // the probes are in
            if (!adaptive || seen == 0u) break;          // every ray traced, or all blocked
            if (seen == probes) return all_of_run;       // all lit
        }
        uint at = (k0 + k) * wave_slot_stride + q;
        vec3 c = wave_shadows[at].light.rgb;
        if (!rest) all_of_run += c;
        bool first_sweep = !adaptive || is_probe(k, m, probes);  // a probe, or every ray
        if (first_sweep == rest) continue;  // not this sweep's
        vec4 o = wave_shadows[at].origin;
        vec4 d = wave_shadows[at].direction;
        traced_rays += 1u;
        if (!trace_any(Ray(o.xyz, o.w, d.xyz, d.w))) {
            sum += c;
            seen += rest ? 0u : 1u;
        }
    }
    return sum;
}

#endif
void trace_shadows(uint q) {
    uint n = floatBitsToUint(wave_paths[q].throughput.w);
    vec3 sum = vec3(0.0);
#if ADAPTIVE_SHADOWS
    for (uint k0 = 0u; k0 < n;) {  // the item's slots, one light's run at a time
        float light = wave_shadows[k0 * wave_slot_stride + q].light.w;
        uint k1 = k0 + 1u;
        while (k1 < n && wave_shadows[k1 * wave_slot_stride + q].light.w == light) ++k1;
        sum += adaptive_run(q, k0, k1 - k0);
        k0 = k1;
    }
#else
    for (uint k = 0u; k < n; ++k) {
        uint at = k * wave_slot_stride + q;
        vec4 o = wave_shadows[at].origin;
        vec4 d = wave_shadows[at].direction;
        traced_rays += 1u;
        if (!trace_any(Ray(o.xyz, o.w, d.xyz, d.w)))
            sum += wave_shadows[at].light.rgb;
    }
#endif
#ifdef WAVE_FINISH
    imageStore(hdr_out, wave_pixel(q), vec4(wave_paths[q].radiance.rgb + sum, 1.0));
#else
    if (n > 0u)
        wave_paths[q].radiance.rgb += sum;
#endif
}
void main() {
    WAVE_FOR_EACH_RAY(k, wave_args[wave_items].w) trace_shadows(wave_ray(k));
    COUNT_RAYS(1, traced_rays);
}
#endif
#endif
