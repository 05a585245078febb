#version 430
// Denoise: SVGF-style edge-aware à-trous wavelet filter (Schied et al. 2017; rayvr/passes/denoise.py),
// over the pixel lists of the effects the config denoises (rt/pixel_list.glsl), both eyes at once.
// Mirrored step by step by rayvr/numpy_denoise.py (the tests compare the two).
//   DENOISE_STAGE 0  every pixel: the accumulated colour as it is (pixels nobody filters), and the
//                    guides packed into 16 bytes (one fetch per tap instead of four)
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
// x view depth (float bits), y octahedral normal (snorm 2x16), z base colour (unorm 4x8), w effect ID
#if DENOISE_STAGE == 0
layout(rgba32ui, binding = IMAGE_DENOISE_GUIDE) uniform writeonly uimage2DArray guide_out;
#else
layout(rgba32ui, binding = IMAGE_DENOISE_GUIDE) uniform readonly uimage2DArray guide_in;
#endif

uniform uint denoise_slot;   // the pixel list (traced effect) this dispatch covers
uniform int step_size;       // 2^iteration
uniform int last_iteration;  // 1: remodulate and write the frame's denoised colour
uniform float sigma_depth, sigma_normal, sigma_luminance, sigma_albedo;

// Octahedral normal encoding (Cigolle et al. 2014): a unit vector in two snorm16 (~1e-4 rad).
vec2 oct_encode(vec3 n) {
    n /= abs(n.x) + abs(n.y) + abs(n.z);
    vec2 s = vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    return n.z >= 0.0 ? n.xy : (1.0 - abs(n.yx)) * s;
}

vec3 oct_decode(vec2 e) {
    vec3 n = vec3(e, 1.0 - abs(e.x) - abs(e.y));
    float t = max(-n.z, 0.0);
    n.x += n.x >= 0.0 ? -t : t;
    n.y += n.y >= 0.0 ? -t : t;
    return normalize(n);
}

struct Guide { float depth; vec3 normal; vec3 albedo; uint effect; };

Guide unpack_guide(uvec4 g) {
    return Guide(uintBitsToFloat(g.x), oct_decode(unpackSnorm2x16(g.y)), unpackUnorm4x8(g.z).rgb, g.w);
}

#if DENOISE_STAGE != 0
// The guide at q, and whether q exists and shows the centre's effect (only such taps count).
bool tap(ivec3 q, uint effect, out Guide g) {
    if (any(lessThan(q.xy, ivec2(0))) || any(greaterThanEqual(q.xy, imageSize(guide_in).xy))) return false;
    g = unpack_guide(imageLoad(guide_in, q));
    return g.effect == effect;
}

struct Centre { Guide g; vec2 grad; float lum; float sigma_l; };

// Screen-space depth gradient at p: per axis the smaller one-sided difference (a silhouette
// next to p does not tilt the plane of p), 0 where neither neighbour is the same kind.
vec2 depth_gradient(ivec3 p, Guide c) {
    vec2 g;
    for (int a = 0; a < 2; a++) {
        ivec3 o = ivec3(a == 0 ? 1 : 0, a == 1 ? 1 : 0, 0);
        Guide fg, bg;
        bool hf = tap(p + o, c.effect, fg), hb = tap(p - o, c.effect, bg);
        float f = hf ? fg.depth - c.depth : 0.0, b = hb ? c.depth - bg.depth : 0.0;
        g[a] = hf && hb ? (abs(f) < abs(b) ? f : b) : (hf ? f : b);
    }
    return g;
}

// Edge-stops (SVGF's depth, normal; an albedo term): a tap's weight against the centre.
float geometry_weight(Centre c, Guide q, ivec2 offset) {
    float wz = exp(-abs(c.g.depth - q.depth) /
                   (sigma_depth * abs(dot(c.grad, vec2(offset))) + 1e-3 * c.g.depth + 1e-12));
    float wn = pow(max(0.0, dot(c.g.normal, q.normal)), sigma_normal);
    vec3 da = c.g.albedo - q.albedo;
    float wa = exp(-dot(da, da) / (sigma_albedo * sigma_albedo));
    return wz * wn * wa;
}
#endif

const float B3[3] = float[3](3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0);  // (1 4 6 4 1) / 16

void main() {
#if DENOISE_STAGE == 0
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p.xy, imageSize(filter_out).xy))) return;
    imageStore(filter_out, p, vec4(finite_or_zero(imageLoad(color_in, p).rgb), 1.0));
    vec3 n = texelFetch(gb_normal, p, 0).xyz;
    n = dot(n, n) > 0.0 ? n : vec3(0.0, 0.0, 1.0);  // background: any unit vector
    imageStore(guide_out, p, uvec4(floatBitsToUint(texelFetch(gb_position, p, 0).w), packSnorm2x16(oct_encode(n)),
                                   packUnorm4x8(vec4(texelFetch(gb_albedo, p, 0).rgb, 0.0)),
                                   texelFetch(gb_material, p, 0).y));
#else
    ivec3 p;
    if (!rt_list_item(denoise_slot, p)) return;
    Centre c;
    c.g = unpack_guide(imageLoad(guide_in, p));
    c.grad = depth_gradient(p, c.g);
    Guide q;
#if DENOISE_STAGE == 1
    vec4 accum = imageLoad(color_in, p);
    // demodulated by the G-buffer's own albedo (the guide's is rounded to 8 bits: edge-stops only)
    vec3 illum = finite_or_zero(accum.rgb) / demodulation_albedo(texelFetch(gb_albedo, p, 0).rgb);
    float var;
    if (accum.a >= 4.0) {  // the spread of the samples, over their count: the variance of the mean
        vec2 m = imageLoad(moments_in, p).xy;
        var = max(m.y - m.x * m.x, 0.0) / accum.a;
    } else {  // too few samples: the spread of the neighbours on the same surface
        float sw = 0.0, s1 = 0.0, s2 = 0.0;
        for (int dy = -3; dy <= 3; dy++) {
            for (int dx = -3; dx <= 3; dx++) {
                ivec3 qp = p + ivec3(dx, dy, 0);
                if (!tap(qp, c.g.effect, q)) continue;
                float w = (dx == 0 && dy == 0) ? 1.0 : geometry_weight(c, q, ivec2(dx, dy));
                float l = luminance(finite_or_zero(imageLoad(color_in, qp).rgb) /
                                    demodulation_albedo(texelFetch(gb_albedo, qp, 0).rgb));
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
            ivec3 qp = p + ivec3(dx, dy, 0);
            if (!tap(qp, c.g.effect, q)) continue;
            float k = (dx == 0 ? 0.5 : 0.25) * (dy == 0 ? 0.5 : 0.25);
            vs += k * imageLoad(filter_in, qp).a; vw += k;
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
            ivec3 qp = p + ivec3(o, 0);
            if (!tap(qp, c.g.effect, q)) continue;
            vec4 v = imageLoad(filter_in, qp);
            float wl = exp(-abs(c.lum - luminance(v.rgb)) / c.sigma_l);
            float w = B3[abs(dx)] * B3[abs(dy)] * geometry_weight(c, q, o) * wl;
            sum_w += w; sum_c += w * v.rgb; sum_v += w * w * v.a;
        }
    }
    vec3 illum = sum_c / sum_w;
    if (last_iteration != 0)
        imageStore(filter_out, p, vec4(illum * demodulation_albedo(texelFetch(gb_albedo, p, 0).rgb), 1.0));
    else
        imageStore(filter_out, p, vec4(illum, sum_v / (sum_w * sum_w)));
#endif
#endif
}
