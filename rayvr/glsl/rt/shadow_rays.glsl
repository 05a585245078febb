// Shadow rays for glsl/common/lighting.glsl: light_visibility() traces an any-hit ray through the
// BVH, and rect lights get `area_samples` random points per pixel (a Fibonacci lattice, randomly
// shifted per pixel: stratified in both axes, so the estimate converges as samples grow) instead
// of the raster's fixed grid. Include before lighting.glsl; set the two globals per surface.
#ifndef RAYVR_RT_SHADOW_RAYS_GLSL
#define RAYVR_RT_SHADOW_RAYS_GLSL
#define HAS_LIGHT_VISIBILITY
#define HAS_RECT_LIGHT_SAMPLES
#include "../accel/bvh.glsl"

vec3 shadow_geometric_normal;  // unit geometric normal of the surface being lit (either side)
int shadow_area_samples = 1;   // points per rect light
vec2 shadow_lattice_shift;     // per-pixel random shift of the lattice

int rect_light_sample_count() { return shadow_area_samples; }

vec2 rect_light_sample(int k, int n) {
    const float golden = 0.6180339887498949;
    return fract(vec2((float(k) + 0.5) / float(n), float(k) * golden) + shadow_lattice_shift);
}

// The ray starts off the surface on the light's side of the *geometric* normal (the G-buffer's
// shading normal may point elsewhere) and stops just short of the light: a rect light's own
// emissive triangles lie at the sample point.
float light_visibility(vec3 p, vec3 n, vec3 to_light, float dist) {
    vec3 ng = dot(shadow_geometric_normal, to_light) >= 0.0 ? shadow_geometric_normal : -shadow_geometric_normal;
    Ray r = Ray(offset_ray(p, ng), 0.0, to_light, dist * (1.0 - 1e-4));
    return trace_any(r) ? 0.0 : 1.0;
}

#endif
