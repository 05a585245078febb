// Metallic-roughness GGX (Trowbridge-Reitz) with Smith height-correlated visibility and a
// Lambert diffuse lobe; roughness is perceptual (alpha = roughness^2).
#ifndef RAYVR_BRDF_GLSL
#define RAYVR_BRDF_GLSL

const float PI = 3.14159265358979;

float ggx_d(float n_h, float alpha) {
    float a2 = alpha * alpha;
    float d = n_h * n_h * (a2 - 1.0) + 1.0;
    return a2 / max(PI * d * d, 1e-12);
}

float smith_visibility(float n_v, float n_l, float alpha) {
    float a2 = alpha * alpha;
    float gv = n_l * sqrt(n_v * n_v * (1.0 - a2) + a2);
    float gl = n_v * sqrt(n_l * n_l * (1.0 - a2) + a2);
    return 0.5 / max(gv + gl, 1e-12);
}

vec3 fresnel_schlick(vec3 f0, float v_h) {
    return f0 + (1.0 - f0) * pow(1.0 - clamp(v_h, 0.0, 1.0), 5.0);
}

// BRDF * cos(theta_l) for unit vectors n (normal), v (to viewer), l (to light), by lobe: the
// Lambert (diffuse) and GGX (specular) parts, weighed separately by effects that sample one lobe.
void brdf_cos_lobes(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness,
                    out vec3 diffuse, out vec3 spec) {
    diffuse = spec = vec3(0.0);
    float n_l = dot(n, l);
    float n_v = max(dot(n, v), 1e-4);
    if (n_l <= 0.0) return;
    vec3 h = v + l;  // l = -v (a viewer below the shading normal): no half vector, take n
    h = dot(h, h) > 1e-20 ? normalize(h) : n;
    float alpha = max(roughness * roughness, 1e-3);
    vec3 f0 = mix(vec3(0.04), base_color, metallic);
    vec3 f = fresnel_schlick(f0, dot(v, h));
    spec = f * ggx_d(max(dot(n, h), 0.0), alpha) * smith_visibility(n_v, n_l, alpha) * n_l;
    diffuse = (1.0 - f) * (1.0 - metallic) * base_color / PI * n_l;
}

vec3 brdf_cos(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness) {
    vec3 diffuse, spec;
    brdf_cos_lobes(n, v, l, base_color, metallic, roughness, diffuse, spec);
    return diffuse + spec;
}

#endif
