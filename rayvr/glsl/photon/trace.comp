#version 430
// Photon tracing (frame/effects/photon/trace.py): one invocation per photon path. A light is picked in
// proportion to its power (photon_lights: per light the power one path carries, rgb, and the
// cumulative probability, w), the photon leaves it (point: uniform sphere; rect: cosine about its
// normal, or about either normal when two-sided; directional: a disc over the scene's bounding
// sphere) and is traced through the BVH.
// Mirror and glossy surfaces (reflective effects) reflect it (Fresnel, GGX lobe for glossy);
// diffuse ones store it -- except at the first hit, which direct light with shadow rays already
// covers -- and bounce it on by Russian roulette on the albedo (cosine-weighted). A path ends when
// it has stored photon_stores photons; reflections do not count against that, only against
// photon_reflections (facing mirrors would reflect it forever). Path i writes its photons to
// slots i * photon_stores + j in order; unused slots keep extra = 0 (empty).
// Random numbers come from the path index and the frame seed: one photon map per frame, shared by
// both eyes, the same for the same seed.
#include "../layout.glsl"  // PHOTON_TRACE_GROUP: rayvr/frame/effects/photon/trace.py
layout(local_size_x = PHOTON_TRACE_GROUP) in;
#include "../rt/hit_surface.glsl"
#include "../common/ggx_sample.glsl"
#include "../common/random.glsl"
#include "photon.glsl"

layout(std430, binding = SSBO_PHOTONS) writeonly restrict buffer Photons { Photon photons[]; };
layout(std430, binding = SSBO_PHOTON_LIGHTS) readonly restrict buffer PhotonLights { vec4 photon_lights[]; };

uniform uint photon_paths;
uniform int photon_stores;   // = bounces: photons a path may store
uniform int photon_reflections;  // mirror/glossy reflections a path may take
uniform uint photon_seed;
uniform vec4 scene_sphere;   // xyz centre (scene-local), w radius: directional lights' disc

bool is_specular(uint effect) {
    return effect < 32u && ((REFLECTIVE_EFFECTS >> effect) & 1u) != 0u;
}

vec3 sample_sphere(vec2 u) {
    float z = 1.0 - 2.0 * u.x, r = sqrt(max(1.0 - z * z, 0.0)), phi = 2.0 * PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), z);
}

vec3 sample_cosine(vec3 n, vec2 u) {
    float r = sqrt(u.x), phi = 2.0 * PI * u.y;
    return basis_around(n) * vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
}

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;
    if (i >= photon_paths) return;
    uint base = i * uint(photon_stores);
    for (int j = 0; j < photon_stores; ++j)
        photons[base + uint(j)] = Photon(vec4(0.0), vec4(0.0));
    uint rng = pcg_hash(i ^ pcg_hash(photon_seed ^ 0x5bd1e995u));
    float u = rng_next(rng);
    // the first light whose running sum exceeds u. Not `while (l < n - 1 && u >= sum[l]) ++l`: llvmpipe
    // (Mesa 22.3) ran that so that the first light's paths read no power, and only a two-light test
    // (tests/test_photon_levels.py) showed it
    int l = 0;
    for (int k = 0; k < lights.length() - 1; ++k)
        if (u >= photon_lights[k].w) l = k + 1;
    Light li = lights[l];
    vec3 power = photon_lights[l].rgb;
    int kind = int(li.position_kind.w);
    vec3 o, dir;
    if (kind == LIGHT_POINT) {
        o = li.position_kind.xyz;
        dir = sample_sphere(rng_next2(rng));
    } else if (kind == LIGHT_RECT) {
        vec2 s = rng_next2(rng) * 2.0 - 1.0;
        vec3 ln = normalize(cross(li.u.xyz, li.v.xyz));
        if (light_two_sided(li) && rng_next(rng) < 0.5) ln = -ln;  // either face, half the power each
        o = li.position_kind.xyz + s.x * li.u.xyz + s.y * li.v.xyz;
        dir = sample_cosine(ln, rng_next2(rng));
        o = offset_ray(o, ln);
    } else {  // directional: a disc of the bounding sphere's radius, outside it, facing along dir
        dir = normalize(li.direction.xyz);
        vec2 s = rng_next2(rng);
        float r = scene_sphere.w * sqrt(s.x), phi = 2.0 * PI * s.y;
        mat3 b = basis_around(dir);
        o = scene_sphere.xyz - dir * (1.01 * scene_sphere.w) + b[0] * (r * cos(phi)) + b[1] * (r * sin(phi));
    }
    int stored = 0, reflections = 0;
    // every diffuse hit after the first stores a photon: at most photon_stores + 1 of them
    for (int hit = 0; stored < photon_stores; ++hit) {
        if (all(equal(power, vec3(0.0)))) break;
        Hit h;
        trace_closest(Ray(o, 0.0, dir, 3.0e38), h);
        if (h.prim == BVH_MISS) break;
        vec3 ng;
        Surface s = surface_at_hit(h, dir, ng);
        vec3 v = -dir;
        if (is_specular(s.effect)) {
            if (++reflections > photon_reflections) break;
            vec3 f0 = mix(vec3(0.04), s.base_color, s.metallic);
            vec3 n = s.normal;
            if (s.effect == uint(EFFECT_GLOSSY) && s.roughness > 0.0) {
                float alpha = max(s.roughness * s.roughness, 1e-3);
                mat3 tbn = basis_around(n);
                vec3 vl = v * tbn;
                vl.z = max(vl.z, 1e-4);
                vec3 m = tbn * sample_ggx_vndf(normalize(vl), alpha, rng_next2(rng));
                dir = reflect(-v, m);
                float n_l = dot(n, dir);
                if (n_l <= 0.0) break;
                power *= fresnel_schlick(f0, dot(v, m)) * smith_g2_over_g1(vl.z, n_l, alpha);
            } else {
                dir = reflect(-v, n);
                power *= fresnel_schlick(f0, dot(n, v));
            }
            if (dot(dir, ng) <= 0.0) dir = reflect(dir, ng);  // shading normal sent it under the surface
        } else {
            if (hit > 0) {
                photons[base + uint(stored)] = Photon(vec4(s.position, uintBitsToFloat(oct_encode(ng))),
                                                      vec4(power, uintBitsToFloat(1u)));
                ++stored;
            }
            vec3 albedo = s.base_color * (1.0 - s.metallic);
            float q = max(albedo.r, max(albedo.g, albedo.b));
            if (rng_next(rng) >= q) break;  // Russian roulette: survivors carry power * albedo / q
            power *= albedo / q;
            vec3 n = dot(s.normal, ng) > 0.0 ? s.normal : ng;
            dir = sample_cosine(n, rng_next2(rng));
            if (dot(dir, ng) <= 0.0) break;
        }
        o = offset_ray(s.position, ng);
    }
}
