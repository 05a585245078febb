#version 430
// Denoise: SVGF-style edge-aware à-trous wavelet filter (Schied et al. 2017; rayvr/passes/denoise.py),
// over the pixel lists of the effects the config denoises (rt/pixel_list.glsl), both eyes at once.
// Mirrored step by step by rayvr/numpy_denoise.py (the tests compare the two).
//   DENOISE_STAGE 0  every pixel: the accumulated colour as it is (pixels nobody filters)
//   DENOISE_STAGE 1  listed pixels: demodulate albedo, estimate the variance of the luminance
//                    (temporal moments from 4 samples on, else spatially over 7x7)
//   DENOISE_STAGE 2  listed pixels: one à-trous iteration, 5x5 B3-spline taps 2^i pixels apart,
//                    weighted by depth, normal, albedo and variance-scaled luminance; the last
//                    iteration multiplies the albedo back and writes the output
#include "../rt/pixel_list.glsl"
#include "../common/gbuffer.glsl"
#include "demodulate.glsl"

#if DENOISE_STAGE == 0
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#else
layout(local_size_x = RT_LOCAL_SIZE, local_size_y = 1, local_size_z = 1) in;
#endif

layout(rgba32f, binding = IMAGE_DENOISE_COLOR) uniform readonly image2DArray color_in;  // rgb accumulated, a samples
layout(rgba32f, binding = IMAGE_DENOISE_MOMENTS) uniform readonly image2DArray moments_in;
layout(rgba32f, binding = IMAGE_DENOISE_IN) uniform readonly image2DArray filter_in;  // rgb demodulated, a variance
layout(rgba32f, binding = IMAGE_DENOISE_OUT) uniform writeonly image2DArray filter_out;

uniform uint denoise_slot;   // the pixel list (traced effect) this dispatch covers
uniform int step_size;       // 2^iteration
uniform int last_iteration;  // 1: remodulate and write the frame's denoised colour
uniform float sigma_depth, sigma_normal, sigma_luminance, sigma_albedo;

// Edge-stops (SVGF, with an albedo term): the 5x5 taps' weights against the centre.
struct Centre { float depth; vec2 grad; vec3 normal; vec3 albedo; uint effect; float lum; float sigma_l; };

bool same_kind(ivec3 q, uint effect) {
    return all(greaterThanEqual(q.xy, ivec2(0))) && all(lessThan(q.xy, imageSize(color_in).xy)) &&
           texelFetch(gb_material, q, 0).y == effect;
}

vec3 guide_normal(ivec3 q) {
    vec3 n = texelFetch(gb_normal, q, 0).xyz;
    return n * inversesqrt(max(dot(n, n), 1e-30));
}

float view_depth(ivec3 q) { return texelFetch(gb_position, q, 0).w; }

// Screen-space depth gradient at p: per axis the smaller one-sided difference (a silhouette
// next to p does not tilt the plane of p), 0 where neither neighbour is the same kind.
vec2 depth_gradient(ivec3 p, uint effect, float z) {
    vec2 g;
    for (int a = 0; a < 2; a++) {
        ivec3 o = ivec3(a == 0 ? 1 : 0, a == 1 ? 1 : 0, 0);
        bool hf = same_kind(p + o, effect), hb = same_kind(p - o, effect);
        float f = hf ? view_depth(p + o) - z : 0.0, b = hb ? z - view_depth(p - o) : 0.0;
        g[a] = hf && hb ? (abs(f) < abs(b) ? f : b) : (hf ? f : b);
    }
    return g;
}

float geometry_weight(Centre c, ivec3 q, ivec2 offset) {
    float z = view_depth(q);
    float wz = exp(-abs(c.depth - z) / (sigma_depth * abs(dot(c.grad, vec2(offset))) + 1e-3 * c.depth + 1e-12));
    float wn = pow(max(0.0, dot(c.normal, guide_normal(q))), sigma_normal);
    vec3 da = c.albedo - texelFetch(gb_albedo, q, 0).rgb;
    float wa = exp(-dot(da, da) / (sigma_albedo * sigma_albedo));
    return wz * wn * wa;
}

Centre centre(ivec3 p) {
    Centre c;
    c.depth = view_depth(p);
    c.effect = texelFetch(gb_material, p, 0).y;
    c.grad = depth_gradient(p, c.effect, c.depth);
    c.normal = guide_normal(p);
    c.albedo = texelFetch(gb_albedo, p, 0).rgb;
    return c;
}

const float B3[3] = float[3](3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0);  // (1 4 6 4 1) / 16

void main() {
#if DENOISE_STAGE == 0
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p.xy, imageSize(filter_out).xy))) return;
    imageStore(filter_out, p, vec4(finite_or_zero(imageLoad(color_in, p).rgb), 1.0));
#else
    ivec3 p;
    if (!rt_list_item(denoise_slot, p)) return;
    Centre c = centre(p);
#if DENOISE_STAGE == 1
    vec4 accum = imageLoad(color_in, p);
    vec3 illum = finite_or_zero(accum.rgb) / demodulation_albedo(c.albedo);
    float var;
    if (accum.a >= 4.0) {  // the spread of the samples, over their count: the variance of the mean
        vec2 m = imageLoad(moments_in, p).xy;
        var = max(m.y - m.x * m.x, 0.0) / accum.a;
    } else {  // too few samples: the spread of the neighbours on the same surface
        float sw = 0.0, s1 = 0.0, s2 = 0.0;
        for (int dy = -3; dy <= 3; dy++) {
            for (int dx = -3; dx <= 3; dx++) {
                ivec3 q = p + ivec3(dx, dy, 0);
                if (!same_kind(q, c.effect)) continue;
                float w = (dx == 0 && dy == 0) ? 1.0 : geometry_weight(c, q, ivec2(dx, dy));
                float l = luminance(finite_or_zero(imageLoad(color_in, q).rgb) /
                                    demodulation_albedo(texelFetch(gb_albedo, q, 0).rgb));
                sw += w; s1 += w * l; s2 += w * l * l;
            }
        }
        s1 /= sw; s2 /= sw;
        var = max(s2 - s1 * s1, 0.0);
    }
    imageStore(filter_out, p, vec4(illum, var));
#else
    vec4 centre_value = imageLoad(filter_in, p);
    // The variance at p, blurred 3x3 (Gaussian) over the same kind: a steadier scale for the
    // luminance edge-stop than one pixel's estimate.
    float vs = 0.0, vw = 0.0;
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            ivec3 q = p + ivec3(dx, dy, 0);
            if (!same_kind(q, c.effect)) continue;
            float k = (dx == 0 ? 0.5 : 0.25) * (dy == 0 ? 0.5 : 0.25);
            vs += k * imageLoad(filter_in, q).a; vw += k;
        }
    }
    c.lum = luminance(centre_value.rgb);
    c.sigma_l = sigma_luminance * sqrt(max(vs / vw, 0.0)) + 1e-10;
    float w0 = B3[0] * B3[0];
    float sum_w = w0;
    vec3 sum_c = w0 * centre_value.rgb;
    float sum_v = w0 * w0 * centre_value.a;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            if (dx == 0 && dy == 0) continue;
            ivec2 o = ivec2(dx, dy) * step_size;
            ivec3 q = p + ivec3(o, 0);
            if (!same_kind(q, c.effect)) continue;
            vec4 v = imageLoad(filter_in, q);
            float wl = exp(-abs(c.lum - luminance(v.rgb)) / c.sigma_l);
            float w = B3[abs(dx)] * B3[abs(dy)] * geometry_weight(c, q, o) * wl;
            sum_w += w; sum_c += w * v.rgb; sum_v += w * w * v.a;
        }
    }
    vec3 illum = sum_c / sum_w;
    if (last_iteration != 0)
        imageStore(filter_out, p, vec4(illum * demodulation_albedo(c.albedo), 1.0));
    else
        imageStore(filter_out, p, vec4(illum, sum_v / (sum_w * sum_w)));
#endif
#endif
}
