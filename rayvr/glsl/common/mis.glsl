// Multiple importance sampling (Veach 1997, ch. 9) of light and BSDF samples, power heuristic,
// and the one-sample BSDF sampling of brdf.glsl's two lobes (Lambert by cosine, GGX by visible
// normals) with its pdf, for effects that sample directions (glossy, path).
//
// An effect that also sends BSDF rays towards the lights defines LIGHT_MIS: lighting.glsl then
// weighs each rect-light sample through the effect's light_mis_brdf_cos() (declared in
// lighting.glsl), and a BSDF ray that reaches a rect light's emitter is weighed by
// emission_mis_weight(). Pdfs are "count x pdf" (the techniques' sample counts folded in).
#ifndef RAYVR_MIS_GLSL
#define RAYVR_MIS_GLSL
#include "scene.glsl"
#include "ggx_sample.glsl"

// BSDF samples the surface being lit takes besides its light samples (0: none, the light samples
// keep weight 1). Set per surface before direct_light().
float mis_bsdf_samples = 0.0;

// Power heuristic (beta = 2) weight of technique a against b (count x pdf each); finite for
// zero and infinite pdfs: a technique that cannot make the sample gets weight 0. NaN is tested
// by name: GLSL need not keep IEEE comparisons, and NVIDIA's compiler turns !(a > 0) into a <= 0.
float power_heuristic(float a, float b) {
    if (isnan(a) || !(a > 0.0)) return 0.0;
    if (isnan(b) || !(b > 0.0)) return 1.0;
    if (a >= b) {
        float r = b / a;
        return 1.0 / (1.0 + r * r);
    }
    float r = a / b;
    return r * r / (1.0 + r * r);
}

// Solid-angle pdf of direction l from VNDF sampling (ggx_sample.glsl) seen from v:
// G1(v) D(h) / (4 n.v), with n.v clamped as sample_ggx_vndf's caller clamps it.
float ggx_vndf_pdf(vec3 n, vec3 v, vec3 l, float alpha) {
    vec3 h = v + l;
    if (dot(h, h) <= 1e-20) return 0.0;
    h = normalize(h);
    float n_v = max(dot(n, v), 1e-4);
    float g1 = 1.0 / (1.0 + smith_lambda(n_v, alpha));
    return g1 * ggx_d(max(dot(n, h), 0.0), alpha) / (4.0 * n_v);
}

// Probability of sampling the GGX lobe rather than the Lambert one: the lobes' rough shares of
// the reflected light at this view angle (Fresnel at n.v), kept away from 0 and 1 while both
// lobes reflect something.
float brdf_specular_probability(vec3 n, vec3 v, vec3 base_color, float metallic) {
    vec3 f = fresnel_schlick(mix(vec3(0.04), base_color, metallic), dot(n, v));
    float spec = dot(f, vec3(1.0 / 3.0));
    float diffuse = dot((1.0 - f) * base_color, vec3(1.0 / 3.0)) * (1.0 - metallic);
    if (diffuse <= 0.0) return 1.0;
    return clamp(spec / (spec + diffuse), 0.1, 0.9);
}

// Pdf (solid angle) of sample_brdf() producing l.
float brdf_pdf(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness) {
    float n_l = dot(n, l);
    if (n_l <= 0.0) return 0.0;
    float ps = brdf_specular_probability(n, v, base_color, metallic);
    float alpha = max(roughness * roughness, 1e-3);
    return ps * ggx_vndf_pdf(n, v, l, alpha) + (1.0 - ps) * n_l / PI;
}

// A direction from the BSDF's lobes (u: three uniform numbers); may point below the surface
// (then nothing reflects: the caller ends the path).
vec3 sample_brdf(vec3 n, vec3 v, vec3 base_color, float metallic, float roughness, vec3 u) {
    mat3 tbn = basis_around(n);
    if (u.z < brdf_specular_probability(n, v, base_color, metallic)) {
        vec3 v_local = v * tbn;  // transpose(tbn) * v
        v_local.z = max(v_local.z, 1e-4);
        vec3 m = tbn * sample_ggx_vndf(normalize(v_local), max(roughness * roughness, 1e-3), u.xy);
        return reflect(-v, m);
    }
    float r = sqrt(u.x), phi = 2.0 * PI * u.y;  // cosine-weighted hemisphere
    return tbn * vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
}

// Solid-angle pdf with which direct_light() (lighting.glsl) samples the rect light that the ray
// from `origin` along unit `dir` meets at `q` (its `area_samples` points folded in: x count; with
// --light-picks, x its pick pdf);
// 0 when q is on no rect light; -1 on a one-sided rect light's back, which emits nothing.
float rect_light_pdf(vec3 origin, vec3 dir, vec3 q, float count) {
    for (int i = 0; i < lights.length(); ++i) {
        Light li = lights[i];
        if (int(li.position_kind.w) != LIGHT_RECT) continue;
        vec3 c = li.position_kind.xyz, u = li.u.xyz, w = li.v.xyz;
        vec3 cr = cross(u, w);
        float area = 4.0 * length(cr);
        if (!(area > 0.0)) continue;
        vec3 ln = cr / (0.25 * area);
        vec3 d = q - c;
        float size = length(u) + length(w);
        if (abs(dot(d, ln)) > 1e-4 * size) continue;  // not in the light's plane
        vec2 st = vec2(dot(d, u) / dot(u, u), dot(d, w) / dot(w, w));
        if (any(greaterThan(abs(st), vec2(1.0 + 1e-4)))) continue;
        float cos_light = dot(ln, -dir);
        if (light_two_sided(li)) cos_light = abs(cos_light);
        if (cos_light <= 0.0) return -1.0;
        vec3 e = q - origin;
        return light_pick_pdf(i) * count * dot(e, e) / (cos_light * area);
    }
    return 0.0;
}

// Weight of the emission a BSDF ray (count x pdf `bsdf_pdf`; 0: a delta direction, nothing else
// could find that light) finds at q against the light samples that could have found it; 0 on
// the back of a one-sided rect light (where its geometry's emission is 0 too: triangle_surface).
float emission_mis_weight(vec3 origin, vec3 dir, vec3 q, float bsdf_pdf, float light_count) {
    if (!(bsdf_pdf > 0.0)) return 1.0;
    float light_pdf = rect_light_pdf(origin, dir, q, light_count);
    return light_pdf < 0.0 ? 0.0 : power_heuristic(bsdf_pdf, light_pdf);
}

#endif
