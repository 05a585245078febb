// Albedo demodulation for the denoiser (SVGF): filter irradiance-like values c / albedo, so that
// texture and colour edges are not blurred, and multiply the albedo back afterwards. The floor
// keeps black albedo finite (Falcor uses 0.001). Mirrored by rayvr/reference/denoise.py.
#ifndef RAYVR_POST_DEMODULATE_GLSL
#define RAYVR_POST_DEMODULATE_GLSL

#include "../layout.glsl"  // DEMODULATE_FLOOR: rayvr/frame/passes/accumulate.py

vec3 demodulation_albedo(vec3 base_color) { return max(base_color, vec3(DEMODULATE_FLOOR)); }

// Rec. 709 luminance: what the variance and the luminance edge-stop are measured in.
float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// A sample that is not finite counts as black: one NaN would spread through every filter tap.
vec3 finite_or_zero(vec3 c) { return any(isnan(c)) || any(isinf(c)) ? vec3(0.0) : c; }

#endif
