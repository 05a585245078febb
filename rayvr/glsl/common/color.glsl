// Tonemapping and output encoding.
#ifndef RAYVR_COLOR_GLSL
#define RAYVR_COLOR_GLSL
#include "../layout.glsl"  // TONEMAP_* (rayvr/gl/gpu_layout.py TONEMAPPERS)

// ACES filmic curve, Narkowicz 2015 fit (input is exposure-scaled linear radiance).
vec3 tonemap_aces(vec3 x) {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 tonemap(vec3 c, int op) {
    c = max(c, vec3(0.0));
    if (op == TONEMAP_ACES) return tonemap_aces(c);
    if (op == TONEMAP_REINHARD) return c / (1.0 + c);
    return clamp(c, 0.0, 1.0);
}

vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}

#endif
