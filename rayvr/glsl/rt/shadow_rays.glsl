// Shadow rays for glsl/common/lighting.glsl: shadowed() scales each light (sample) by its
// visibility along a shadow ray, and rect lights get `area_samples` random points per pixel (a
// Fibonacci lattice, randomly shifted per pixel: stratified in both axes, so the estimate converges
// as samples grow) instead of the raster's fixed grid. Include before lighting.glsl; set the
// globals below per surface.
//
// shadowed() traces nothing: it stores the ray and the unshadowed contribution (times
// shadow_weight) in the item's shadow slots of rt/wave.glsl and returns 0; the lean any-hit kernel
// (rt/wave_trace.comp) traces them all and adds the unoccluded contributions. (Tracing on the
// spot, one fat kernel shading and tracing, ran 6-10x slower on the GPU.)
#ifndef RAYVR_RT_SHADOW_RAYS_GLSL
#define RAYVR_RT_SHADOW_RAYS_GLSL
#define HAS_LIGHT_VISIBILITY
#define HAS_RECT_LIGHT_SAMPLES
#define HAS_LIGHT_PICKS
#include "../accel/bvh.glsl"
#include "../common/random.glsl"
#include "wave.glsl"

vec3 shadow_geometric_normal;  // unit geometric normal of the surface being lit (either side)
int shadow_area_samples = 1;   // points per rect light
vec2 shadow_lattice_shift;     // per-pixel random shift of the lattice
uint light_pick_rng;           // the surface's stream of light picks (--light-picks)

// A surface's light sampling state from its random stream: the lattice's shift, and the light
// picks' own stream (hashed off the surface's, which it leaves where it was, so frames without
// picks draw what they always drew).
void light_samples_begin(inout uint rng) {
    shadow_lattice_shift = rng_next2(rng);
    light_pick_rng = pcg_hash(rng ^ 0x68E31DA4u);
}

int rect_light_sample_count() { return shadow_area_samples; }

vec2 rect_light_sample(int k, int n) {
    const float golden = 0.6180339887498949;
    return fract(vec2((float(k) + 0.5) / float(n), float(k) * golden) + shadow_lattice_shift);
}

// The ray starts off the surface on the light's side of the *geometric* normal (the G-buffer's
// shading normal may point elsewhere) and stops just short of the light: a rect light's own
// emissive triangles lie at the sample point.
Ray shadow_ray(vec3 p, vec3 to_light, float dist) {
    vec3 ng = dot(shadow_geometric_normal, to_light) >= 0.0 ? shadow_geometric_normal : -shadow_geometric_normal;
    return Ray(offset_ray(p, ng), 0.0, to_light, dist * (1.0 - 1e-4));
}

uint shadow_item;           // wave item (pixel or path) the rays belong to
int shadow_light;           // the light being sampled (lighting.glsl light_visibility_begin)

// The next shadow rays are light i's: a slot keeps its light's index, so the trace kernel sees each
// light's run of rays (rt/wave_trace.comp adaptive_run).
void light_visibility_begin(int i) { shadow_light = i; }
vec3 shadow_weight;         // throughput of that item's path up to this surface
int shadow_calls;           // shadow rays asked for at this surface so far

vec3 shadowed(vec3 contribution, vec3 p, vec3 n, vec3 to_light, float dist) {
    vec3 c = contribution * shadow_weight;
    if (all(equal(c, vec3(0.0))))
        return vec3(0.0);  // nothing to lose: no ray
    int k = shadow_calls++ - int(wave_slot_first);
    if (k >= 0 && k < int(wave_slot_count)) {  // this chunk of the slots
        Ray r = shadow_ray(p, to_light, dist);
        wave_shadows[uint(k) * wave_slot_stride + shadow_item] =
            ShadowSlot(vec4(r.origin, r.tmin), vec4(r.direction, r.tmax), vec4(c, float(shadow_light)));
    }
    return vec3(0.0);
}

// Call before lighting a surface of item `item` with path weight `weight`.
void shadow_begin(uint item, vec3 weight, vec3 geometric_normal) {
    shadow_item = item;
    shadow_weight = weight;
    shadow_geometric_normal = geometric_normal;
    shadow_calls = 0;
}

// Shadow rays stored for the current item in this chunk.
uint shadow_stored() {
    return uint(clamp(shadow_calls - int(wave_slot_first), 0, int(wave_slot_count)));
}

#endif
