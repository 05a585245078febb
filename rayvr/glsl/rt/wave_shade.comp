#version 430
// The shading kernels of the ray-traced rungs of the effect ladder, one program per effect and
// stage (EFFECT = the effect's ID; the effect's own part of the pixel event comes from the file
// EFFECT_PATHS names: glsl/effects/<effect>.glsl), run by indirect dispatches over a batch of that
// effect's pixel list (rt/wave.glsl), both eyes at once. Rays are not traced here: shadowed() stores shadow rays
// (rt/shadow_rays.glsl) and the stages below store reflection rays, for rt/wave_trace.comp.
//   shadows      emission + direct light with shadow rays (rect lights: area_samples points)
//                + ambient, as `raster` does
//   reflections  + a mirror ray that follows up to `bounces` reflective surfaces, each hit shaded
//                with its own direct light and shadows; misses see the background
//   glossy       + `samples` GGX rays (VNDF importance sampling), each followed like a mirror ray;
//                rect lights by MIS of light and GGX samples
//   path         paths: light samples and BSDF samples at every vertex (MIS), Russian roulette
// A reflective surface (effect reflections or glossy) met along a reflection ray continues it in
// its mirror direction while bounces remain; any other surface ends it. An effect that shades
// path vertices itself (path) defines EFFECT_PATH_VERTEX and path_vertex_begin/_end instead.
//   WAVE_STAGE 3  pixel: light the G-buffer surface, start the pixel's paths
//   WAVE_STAGE 4  hit: light each path's hit (bounce wave_bounce), continue or end the path
//   WAVE_STAGE 5  finish: the pixel's colour = sum of its paths' radiance
// With several chunks of shadow slots (wave_slot_first > 0 on later ones) stages 3 and 4 run once
// per chunk; only the first (stage 3) or the last (stage 4) touches the path state.
#ifndef WAVE_STAGE
#define WAVE_STAGE 3
#endif
#ifndef EFFECT  // built alone: as `shadows` (frame/passes/trace_effect.py passes the effect's own values,
#define EFFECT EFFECT_SHADOWS  // EFFECT_PATHS among them: the loader needs it)
#define RT_SLOT 0
#define PARAM_AREA_SAMPLES PARAM_SHADOWS_AREA_SAMPLES
#endif
#include "pixel_list.glsl"
layout(local_size_x = RT_LOCAL_SIZE) in;  // the lists' groups (classify.comp counts them so)
#include "shadow_rays.glsl"
#include "../common/lighting.glsl"
#include "../common/ggx_sample.glsl"
#include "../common/random.glsl"
#include "../common/camera.glsl"
#include "hit_surface.glsl"

layout(rgba16f, binding = IMAGE_HDR) uniform writeonly image2DArray hdr_out;
uniform vec3 ambient;
uniform vec3 background;
uniform uint frame_seed;
uniform int wave_bounce;      // stage 4: 0 for the first reflection hit
uniform uint wave_last_chunk; // stage 4: 1 on the last chunk of shadow slots

bool is_reflective(uint effect) {
    return effect < 32u && ((REFLECTIVE_EFFECTS >> effect) & 1u) != 0u;
}

// A path's ray leaving p (geometric normal ng) in direction dir, or an ended path (throughput 0).
void start_path(uint p, vec3 origin_p, vec3 ng, vec3 dir, vec3 weight) {
    wave_paths[p].origin = vec4(offset_ray(origin_p, dot(ng, dir) >= 0.0 ? ng : -ng), 0.0);
    wave_paths[p].direction = vec4(dir, 3.0e38);
    wave_paths[p].throughput.rgb = weight;
}

void end_path(uint p) {
    wave_paths[p].direction.w = -1.0;
}

// Path j of pixel i (of n), for effects with `samples` paths per pixel (glossy, path): clears its
// radiance (path 0's is the pixel's own, set by the caller) and ends it when j >= samples.
bool pixel_path(uint i, int j, int samples, out uint p) {
    p = uint(j) * wave_args[0].w + i;
    if (j > 0) wave_paths[p].radiance = vec4(0.0);
    if (j < samples) return true;
    end_path(p);
    return false;
}

// The effect's own part of the pixel event (Effect.shader, e.g. glsl/effects/glossy.glsl):
//   void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng)
// sets the radiance the pixel starts with and starts its reflection paths (start_path/end_path).
#include EFFECT_PATHS

// Per-pixel sampling state, as the pixel's own event set it: same stream, same lattice, seeded
// from the surface point the pixel sees (the same in both eyes: common/random.glsl).
// The pixel's material has this pass's effect: PARAM_* (its parameter slots) apply.
int pixel_area_samples;  // points per rect light at the pixel's own surface (area_samples)

uint pixel_setup(ivec3 px, out uint rng) {
    uint mi = texelFetch(gb_material, px, 0).x;
    vec4 position = texelFetch(gb_position, px, 0);  // xyz scene-local, w view depth
    vec4 t = eye_tangents[px.z];
    float footprint = position.w * (t.w - t.z) / float(textureSize(gb_material, 0).y);
    rng = rng_seed_surface(position.xyz, footprint, frame_seed);
    pixel_area_samples = max(material_param_int(mi, PARAM_AREA_SAMPLES), 1);
    shadow_area_samples = pixel_area_samples;
    light_samples_begin(rng);
#ifdef LIGHT_MIS  // the pixel's light samples against its `samples` BSDF rays
    mis_bsdf_samples = float(max(material_param_int(mi, PARAM_SAMPLES), 1));
#endif
#if WAVE_STAGE == 3 && defined(PIXEL_LIGHT_SAMPLES_PER_PATH)  // a set of light samples per path
    shadow_area_samples *= max(material_param_int(mi, PARAM_SAMPLES), 1);
#endif
    return mi;
}

#if WAVE_STAGE == 4 && !defined(EFFECT_PATH_VERTEX)
// The hit event of the reflection effects: mirror rays (delta directions) take no part in MIS.
// Where a reflection ray lands, its surface is lit with `hit_area_samples` points per rect light,
// by default (0) the pixel's area_samples spread over the rays it sent (at least one a ray): the
// pixel averages its rays' hits, so a glossy floor's 4 rays cast 4 shadow rays there, not
// 4 x area_samples, and a mirror's one ray keeps area_samples. Each path and bounce draws its own
// lattice shift, so a pixel's rays sample different points of a light (the pixel's stream hashed
// with path and bounce: still the same in both eyes).
#ifndef EFFECT_PIXEL_RAYS
#ifdef PARAM_SAMPLES
int effect_pixel_rays(uint mi, ivec3 px) { return max(material_param_int(mi, PARAM_SAMPLES), 1); }
#else
int effect_pixel_rays(uint mi, ivec3 px) { return 1; }
#endif
#endif

void path_vertex_begin(uint p, uint mi, ivec3 px, inout uint rng) {
    mis_bsdf_samples = 0.0;
#ifdef PARAM_HIT_AREA_SAMPLES
    int hit = material_param_int(mi, PARAM_HIT_AREA_SAMPLES);
    int rays = effect_pixel_rays(mi, px);
    shadow_area_samples = hit > 0 ? hit : max((pixel_area_samples + rays - 1) / rays, 1);
#endif
    uint r = pcg_hash(rng ^ pcg_hash((p / wave_args[0].w) * 131u + uint(wave_bounce) + 0x2C1B3C6Du));
    light_samples_begin(r);
}

// The hit's emission (MIS-weighted against the light samples when the ray was a BSDF sample:
// radiance.w > 0, glossy's first bounce) and ambient term; a reflective surface continues the
// ray in its mirror direction while bounces remain, any other ends it.
void path_vertex_end(uint p, Surface s, vec3 v, vec3 hng, uint mi, inout uint rng, vec3 throughput) {
    // radiance.w > 0 only on the first bounce: the light samples it is weighed against are the pixel's
    vec3 emission = s.emission * emission_mis_weight(wave_paths[p].origin.xyz, -v, s.position,
                                                     wave_paths[p].radiance.w, float(pixel_area_samples));
    int bounces = max(material_param_int(mi, PARAM_BOUNCES), 1);
    if (!is_reflective(s.effect) || wave_bounce >= bounces - 1) {
        wave_paths[p].radiance.rgb += throughput * (emission + ambient * s.base_color);
        end_path(p);
        return;
    }
    wave_paths[p].radiance.rgb += throughput * (emission + ambient * s.base_color * (1.0 - s.metallic));
    vec3 weight = throughput * fresnel_schlick(mix(vec3(0.04), s.base_color, s.metallic), dot(s.normal, v));
    vec3 dir = reflect(-v, s.normal);
    if (dot(dir, hng) <= 0.0) dir = reflect(dir, hng);  // shading normal sent it under the surface
    start_path(p, s.position, hng, dir, weight);
    wave_paths[p].radiance.w = 0.0;  // a mirror direction: no light sample could find it
}
#endif

#if WAVE_STAGE == 3
void main() {
    uint i = wave_index();
    if (i >= wave_args[0].w) return;
    ivec3 px = wave_pixel(i);
    Surface s = gbuffer_fetch(px);
    vec3 v = normalize(eye_position[px.z] - s.position);
    s.position = point_on_triangle(s.triangle, s.position);  // where its rays start
    vec3 ng = normalize(triangle_normal(scene_triangle(s.triangle)));
    if (dot(ng, v) < 0.0) ng = -ng;
    uint rng;
    uint mi = pixel_setup(px, rng);
    shadow_begin(i, vec3(1.0), ng);
    direct_light(s.position, s.normal, v, s.base_color, s.metallic, s.roughness);
    wave_paths[i].throughput.w = uintBitsToFloat(shadow_stored());
    if (wave_slot_first != 0u) return;  // later chunks only add shadow rays
    effect_start_paths(i, s, v, ng, mi, rng);
}

#elif WAVE_STAGE == 4
void main() {
    uint p = wave_index();
    if (p >= wave_args[1].w) return;
    uvec4 hb = wave_paths[p].hit;
    if (hb.x == WAVE_IDLE || hb.x == BVH_MISS) {
        wave_paths[p].throughput.w = uintBitsToFloat(0u);
        if (hb.x == BVH_MISS && wave_last_chunk != 0u) {
            wave_paths[p].radiance.rgb += wave_paths[p].throughput.rgb * background;
            end_path(p);
        }
        return;
    }
    uint n = wave_args[0].w;
    ivec3 px = wave_pixel(p % n);
    uint rng;
    uint mi = pixel_setup(px, rng);
    path_vertex_begin(p, mi, px, rng);
    vec3 dir = wave_paths[p].direction.xyz;
    vec3 throughput = wave_paths[p].throughput.rgb;
    Hit h;
    h.t = 0.0;
    h.slot = hb.x;
    h.prim = hb.y;
    h.uv = uintBitsToFloat(hb.zw);
    vec3 hng;
    Surface s = surface_at_hit(h, dir, hng);
    shadow_begin(p, throughput, hng);
    direct_light(s.position, s.normal, -dir, s.base_color, s.metallic, s.roughness);
    wave_paths[p].throughput.w = uintBitsToFloat(shadow_stored());
    if (wave_last_chunk == 0u) return;
    path_vertex_end(p, s, -dir, hng, mi, rng, throughput);
}

#else  // WAVE_STAGE 5
void main() {
    uint i = wave_index();
    uint n = wave_args[0].w;
    if (i >= n) return;
    vec3 color = vec3(0.0);
    for (uint j = 0u; j < wave_paths_per_pixel; ++j)
        color += wave_paths[j * n + i].radiance.rgb;
    imageStore(hdr_out, wave_pixel(i), vec4(color, 1.0));
}
#endif
