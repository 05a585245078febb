// Importance sampling of the GGX specular lobe through its distribution of visible normals
// (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4)). With the
// height-correlated Smith term of brdf.glsl, the estimator's weight f * cos / pdf reduces to
// F * G2(v, l) / G1(v): no D, no division by small cosines, so it stays bounded at grazing angles.
#ifndef RAYVR_GGX_SAMPLE_GLSL
#define RAYVR_GGX_SAMPLE_GLSL
#include "brdf.glsl"

// Orthonormal basis around unit n (Duff et al. 2017, branchless, no NaN at n = -z).
mat3 basis_around(vec3 n) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float b = n.x * n.y * a;
    vec3 t = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    vec3 bt = vec3(b, s + n.y * n.y * a, -n.y);
    return mat3(t, bt, n);
}

// A microfacet normal (tangent space, z = surface normal) visible from v (tangent space, v.z > 0).
vec3 sample_ggx_vndf(vec3 v, float alpha, vec2 u) {
    vec3 vh = normalize(vec3(alpha * v.x, alpha * v.y, v.z));
    float len2 = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = len2 > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0)) * vh;
    return normalize(vec3(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-6)));
}

float smith_lambda(float cos_theta, float alpha) {
    float c2 = max(cos_theta * cos_theta, 1e-12);
    return 0.5 * (-1.0 + sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2));
}

// G2(v, l) / G1(v) for the height-correlated Smith masking-shadowing.
float smith_g2_over_g1(float n_v, float n_l, float alpha) {
    float lv = smith_lambda(n_v, alpha);
    return (1.0 + lv) / (1.0 + lv + smith_lambda(n_l, alpha));
}

#endif
