#version 430
// The ray-traced rungs of the effect ladder, one program per effect (EFFECT = its ID), run by an
// indirect dispatch over that effect's pixel list (rt/pixel_list.glsl), both eyes at once. Each
// pixel overwrites the raster result in the HDR target:
//   shadows      emission + direct light with shadow rays (rect lights: area_samples points)
//                + ambient, as `raster` does
//   reflections  + a mirror ray that follows up to `bounces` reflective surfaces, each hit shaded
//                with its own direct light and shadows; misses see the background
//   glossy       + `samples` GGX rays (VNDF importance sampling), each followed like a mirror ray
// A reflective surface (effect reflections or glossy) met along a reflection ray continues it in
// its mirror direction while bounces remain; any other surface ends it.
layout(local_size_x = 64) in;
#include "shadow_rays.glsl"
#include "../common/lighting.glsl"
#include "../common/ggx_sample.glsl"
#include "../common/random.glsl"
#include "../common/camera.glsl"
#include "hit_surface.glsl"
#include "pixel_list.glsl"
#ifndef EFFECT
#define EFFECT EFFECT_SHADOWS
#define RT_SLOT 0
#endif

layout(rgba16f, binding = 0) uniform writeonly image2DArray hdr_out;
uniform vec3 ambient;
uniform vec3 background;
uniform uint frame_seed;

bool is_reflective(uint effect) {
    return effect == uint(EFFECT_REFLECTIONS) || effect == uint(EFFECT_GLOSSY);
}

// Emission + direct light with shadows at a surface seen from direction v.
vec3 lit(Surface s, vec3 ng, vec3 v) {
    shadow_geometric_normal = ng;
    return s.emission + direct_light(s.position, s.normal, v, s.base_color, s.metallic, s.roughness);
}

// Radiance arriving at p (on a surface with geometric normal ng) from direction dir.
vec3 trace_reflection(vec3 p, vec3 ng, vec3 dir, int bounces) {
    vec3 sum = vec3(0.0);
    vec3 throughput = vec3(1.0);
    for (int b = 0; b < bounces; ++b) {
        Ray r = Ray(offset_ray(p, dot(ng, dir) >= 0.0 ? ng : -ng), 0.0, dir, 3.0e38);
        Hit h;
        if (!trace_closest(r, h)) {
            sum += throughput * background;
            break;
        }
        vec3 hng;
        Surface s = surface_at_hit(h, dir, hng);
        vec3 v = -dir;
        vec3 direct = lit(s, hng, v);
        if (!is_reflective(s.effect) || b == bounces - 1) {
            sum += throughput * (direct + ambient * s.base_color);
            break;
        }
        sum += throughput * (direct + ambient * s.base_color * (1.0 - s.metallic));
        throughput *= fresnel_schlick(mix(vec3(0.04), s.base_color, s.metallic), dot(s.normal, v));
        dir = reflect(dir, s.normal);
        if (dot(dir, hng) <= 0.0) dir = reflect(dir, hng);  // shading normal sent it under the surface
        p = s.position;
        ng = hng;
    }
    return sum;
}

void main() {
    ivec3 px;
    if (!rt_list_item(uint(RT_SLOT), px)) return;
    Surface s = gbuffer_fetch(px);
    vec3 v = normalize(eye_position[px.z] - s.position);
    vec3 ng = triangle_normal(s.triangle);
    if (dot(ng, v) < 0.0) ng = -ng;
    uvec4 params = materials[s.material].params;  // bounces, samples, area_samples
    uint rng = rng_seed(px, frame_seed);
    shadow_area_samples = int(max(params.z, 1u));
    shadow_lattice_shift = rng_next2(rng);
    vec3 color = lit(s, ng, v);
#if EFFECT == EFFECT_SHADOWS
    color += ambient * s.base_color;
#else
    color += ambient * s.base_color * (1.0 - s.metallic);  // the specular share is traced below
    int bounces = int(max(params.x, 1u));
    vec3 f0 = mix(vec3(0.04), s.base_color, s.metallic);
#if EFFECT == EFFECT_REFLECTIONS
    vec3 dir = reflect(-v, s.normal);
    if (dot(dir, ng) <= 0.0) dir = reflect(dir, ng);
    color += fresnel_schlick(f0, dot(s.normal, v)) * trace_reflection(s.position, ng, dir, bounces);
#else  // glossy
    int samples = int(max(params.y, 1u));
    float alpha = max(s.roughness * s.roughness, 1e-3);
    mat3 tbn = basis_around(s.normal);
    vec3 v_local = v * tbn;  // transpose(tbn) * v
    v_local.z = max(v_local.z, 1e-4);
    vec3 acc = vec3(0.0);
    for (int i = 0; i < samples; ++i) {
        vec3 m = tbn * sample_ggx_vndf(normalize(v_local), alpha, rng_next2(rng));
        vec3 l = reflect(-v, m);
        float n_l = dot(s.normal, l);
        if (n_l <= 0.0 || dot(l, ng) <= 0.0) continue;  // below the surface: no light this way
        vec3 weight = fresnel_schlick(f0, dot(v, m)) * smith_g2_over_g1(v_local.z, n_l, alpha);
        acc += weight * trace_reflection(s.position, ng, l, bounces);
    }
    color += acc / float(samples);
#endif
#endif
    imageStore(hdr_out, px, vec4(color, 1.0));
}
