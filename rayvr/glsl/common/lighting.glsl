// Direct lighting from the scene's lights at a surface point.
// A pass that traces shadow rays defines HAS_LIGHT_VISIBILITY and provides
//   vec3 shadowed(vec3 contribution, vec3 p, vec3 n, vec3 to_light, float dist);
// which returns the unshadowed `contribution` of one light (sample) scaled by its visibility, or
// records a shadow ray for it (rt/shadow_rays.glsl), and void light_visibility_begin(int i), told
// which light the next calls sample; without it every light is unoccluded (`raster`).
#ifndef RAYVR_LIGHTING_GLSL
#define RAYVR_LIGHTING_GLSL
#include "scene.glsl"
#include "brdf.glsl"
#include "mis.glsl"

// RECT_LIGHT_GRID (layout.glsl, rayvr/gl/gpu_layout.py): raster: fixed NxN points per rect light

#ifndef HAS_LIGHT_VISIBILITY
vec3 shadowed(vec3 contribution, vec3 p, vec3 n, vec3 to_light, float dist) { return contribution; }
void light_visibility_begin(int i) {}  // shadow_rays.glsl: the light the next shadowed() calls sample
#endif

#ifdef LIGHT_MIS
// The effect's BRDF x cos for a rect-light sample of pdf `light_pdf` (count x solid-angle pdf),
// weighed by MIS against its own BSDF samples (mis.glsl mis_bsdf_samples; glsl/effects/*.glsl).
vec3 light_mis_brdf_cos(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness, float light_pdf);
#endif

// Points on a rect light, in [0,1]^2. A pass that samples them itself (randomly, per pixel)
// defines HAS_RECT_LIGHT_SAMPLES and provides both functions; without it: a fixed NxN grid.
#ifndef HAS_RECT_LIGHT_SAMPLES
int rect_light_sample_count() { return RECT_LIGHT_GRID * RECT_LIGHT_GRID; }
vec2 rect_light_sample(int k, int n) {
    return (vec2(k / RECT_LIGHT_GRID, k % RECT_LIGHT_GRID) + 0.5) / float(RECT_LIGHT_GRID);
}
#endif

// Light i's contribution at the surface, divided by its pick pdf (light_pick_pdf: 1 when every
// light is taken), added to sum sample by sample.
void add_light(int i, vec3 p, vec3 n, vec3 v, vec3 base_color, float metallic, float roughness, float pick_pdf,
               inout vec3 sum) {
    Light li = lights[i];
    int kind = int(li.position_kind.w);
    light_visibility_begin(i);
    if (kind == LIGHT_DIRECTIONAL) {
        vec3 l = -normalize(li.direction.xyz);
        vec3 f = brdf_cos(n, v, l, base_color, metallic, roughness);
        if (any(greaterThan(f, vec3(0.0))))
            sum += shadowed(f * li.radiance.rgb / pick_pdf, p, n, l, 1e30);
    } else if (kind == LIGHT_POINT) {
        vec3 d = li.position_kind.xyz - p;
        float dist = length(d);
        if (dist <= 0.0) return;
        vec3 l = d / dist;
        vec3 f = brdf_cos(n, v, l, base_color, metallic, roughness);
        if (any(greaterThan(f, vec3(0.0))))
            sum += shadowed(f * li.radiance.rgb / (dist * dist) / pick_pdf, p, n, l, dist);
    } else if (kind == LIGHT_RECT) {
        // Radiance L over area A: E = sum L * cos_l * cos_s / d^2 * A / N over N points.
        vec3 c = li.position_kind.xyz, u = li.u.xyz, w = li.v.xyz;
        vec3 ln = normalize(cross(u, w));
        float area = 4.0 * length(cross(u, w));
        if (!(area > 0.0)) return;  // a zero-area light emits nothing (and has no normal)
        int N = rect_light_sample_count();
        for (int k = 0; k < N; ++k) {
            vec2 s = rect_light_sample(k, N) * 2.0 - 1.0;
            vec3 q = c + s.x * u + s.y * w;
            vec3 d = q - p;
            float dist2 = dot(d, d);
            if (dist2 <= 0.0) continue;
            float dist = sqrt(dist2);
            vec3 l = d / dist;
            float cos_light = dot(ln, -l);
            if (light_two_sided(li)) cos_light = abs(cos_light);
            if (cos_light <= 0.0) continue;  // behind a one-sided light
#ifdef LIGHT_MIS
            vec3 f = light_mis_brdf_cos(n, v, l, base_color, metallic, roughness,
                                        pick_pdf * float(N) * dist2 / (cos_light * area));
#else
            vec3 f = brdf_cos(n, v, l, base_color, metallic, roughness);
#endif
            if (!any(greaterThan(f, vec3(0.0)))) continue;
            sum += shadowed(f * li.radiance.rgb * cos_light / dist2 * (area / float(N)) / pick_pdf, p, n, l, dist);
        }
    }
}

vec3 direct_light(vec3 p, vec3 n, vec3 v, vec3 base_color, float metallic, float roughness) {
    vec3 sum = vec3(0.0);
#ifdef HAS_LIGHT_PICKS  // a traced effect (rt/shadow_rays.glsl): with --light-picks, K lights drawn by power
    if (light_picks > 0) {
        for (int j = 0; j < light_picks; ++j) {
            int i = pick_light(rng_next(light_pick_rng));
            float pdf = light_pick_pdf(i);
            if (pdf > 0.0)
                add_light(i, p, n, v, base_color, metallic, roughness, pdf, sum);
        }
        return sum;
    }
#endif
    for (int i = 0; i < lights.length(); ++i)
        add_light(i, p, n, v, base_color, metallic, roughness, 1.0, sum);
    return sum;
}

#endif
