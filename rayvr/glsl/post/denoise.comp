#version 430
// Denoise: SVGF-style edge-aware à-trous wavelet filter (Schied et al. 2017; rayvr/frame/passes/denoise.py)
// of the pixels whose effect the config denoises (bit `effect` of denoise_effects), both eyes at once.
// Mirrored step by step by rayvr/reference/denoise.py (the tests compare the two).
//   DENOISE_STAGE 0  every pixel: the accumulated colour as it is (pixels nobody filters), and the
//                    guides packed into 16 bytes (one fetch per tap instead of four)
//   DENOISE_STAGE 4  denoised pixels (before stage 1): demodulate albedo and clamp outliers (fireflies):
//                    a luminance far above that of the pixel's 5x5 neighbours on its surface
//   DENOISE_STAGE 1  denoised pixels: estimate the variance of the (clamped) demodulated luminance
//                    (temporal moments from 4 samples on, else spatially over 7x7), and the depth
//                    gradient the depth edge-stop uses (once, not per iteration)
//   DENOISE_STAGE 2  denoised pixels: one à-trous iteration, 5x5 B3-spline taps 2^i pixels apart,
//                    weighted by depth, normal, albedo and luminance scaled by the input's variance
//                    blurred 3x3 over the same effect; the last iteration multiplies the albedo back
//                    and writes the output
//   DENOISE_STAGE 3  denoised pixels: that variance blur, ahead of an iteration of step 2 or more
// Stages 1-4 read their taps from workgroup memory: a work group loads the guides and values of a
// 16x16 lattice of pixels `step` apart plus an apron of APRON lattice points once (à-trous taps of
// step 2^i fall on the same lattice), instead of every pixel fetching 25-49 taps itself (4.7 ms at
// 2x1440x1600 on a data-centre GPU that way). A group whose pixels are all undenoised stops after
// one fetch each. The 3x3 variance blur's taps are 1 pixel apart: the first iteration (step 1)
// takes them from its own tile; the others get the blur from a stage-3 dispatch over the step-1
// lattice. (Fetching the 8 neighbours in a step-2^i iteration instead was slower: 2.11 -> 2.30 ms
// for 4 iterations, the room: a lattice group's neighbours are scattered.) The first iteration's
// own blur: the room's denoiser 2.44-3.32 ms against 2.55-3.45 with a blur dispatch before it (4
// head poses). The runs are in docs/results.md.
#include "../common/gbuffer.glsl"
#include "demodulate.glsl"

#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
#if DENOISE_STAGE == 0
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#else
#define TILE DENOISE_TILE  // frame/passes/denoise.py
layout(local_size_x = TILE, local_size_y = TILE, local_size_z = 1) in;
#endif

layout(rgba32f, binding = IMAGE_DENOISE_COLOR) uniform readonly image2DArray color_in;  // rgb accumulated, a samples
layout(rgba32f, binding = IMAGE_DENOISE_MOMENTS) uniform readonly image2DArray moments_in;
layout(rgba32f, binding = IMAGE_DENOISE_IN) uniform readonly image2DArray filter_in;  // rgb demodulated, a variance
layout(rgba32f, binding = IMAGE_DENOISE_OUT) uniform writeonly image2DArray filter_out;
// x, y: view depth gradient per pixel (stage 1 writes, stage 2 reads); the blurred variance (stage 3
// writes, stage 2 reads at steps of 2 or more)
layout(rg32f, binding = IMAGE_DENOISE_GRADIENT) uniform image2DArray gradient_image;
layout(r32f, binding = IMAGE_DENOISE_VARIANCE) uniform image2DArray variance_image;
// x view depth (float bits), y octahedral normal (snorm 2x16), z base colour (unorm 4x8), w effect ID
#if DENOISE_STAGE == 0
layout(rgba32ui, binding = IMAGE_DENOISE_GUIDE) uniform writeonly uimage2DArray guide_out;
#else
layout(rgba32ui, binding = IMAGE_DENOISE_GUIDE) uniform readonly uimage2DArray guide_in;
#endif

uniform uint denoise_effects;  // bit e: pixels of effect e are denoised
uniform int step_size;       // 2^iteration (stage 2)
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


#if DENOISE_STAGE != 0
#if DENOISE_STAGE == 1
#define APRON 3  // the 7x7 spatial variance
#elif DENOISE_STAGE == 3
#define APRON 1  // the 3x3 variance blur
#elif DENOISE_STAGE == 4
#define APRON DENOISE_OUTLIER_RADIUS  // the 5x5 outlier statistics
#else
#define APRON 2  // the 5x5 à-trous taps
#endif
#define SIDE (TILE + 2 * APRON)
#define OUTSIDE 0xFFFFFFFFu  // the effect of a tap outside the image: equal to no centre's

// The tile's guides, decoded once per lattice point rather than once per tap that reads it
shared vec4 tile_shape[SIDE * SIDE];   // xyz normal, w view depth
shared uvec2 tile_look[SIDE * SIDE];   // x base colour (unorm 4x8), y effect (OUTSIDE beyond the image)
shared vec4 tile_value[SIDE * SIDE];
shared uint tile_any;

bool denoised(uint effect) { return effect < 32u && ((denoise_effects >> effect) & 1u) != 0u; }

// The value a stage filters at pixel q: stage 4 the demodulated colour, 1 that clamped (stage 4's
// output), 2 and 3 the previous iteration's (demodulated colour, variance).
vec4 stage_value(ivec3 q) {
#if DENOISE_STAGE == 4
    return vec4(finite_or_zero(imageLoad(color_in, q).rgb) / demodulation_albedo(texelFetch(gb_albedo, q, 0).rgb), 0.0);
#else
    return imageLoad(filter_in, q);
#endif
}

// This invocation's pixel (the lattice point (lx, ly) of its group's tile) and the pixel of its
// group's lattice point (0, 0). Groups in x: (image width / (TILE * step), rounded up) * step; the
// `step` groups of a block of TILE * step columns take one residue modulo step each.
ivec3 lattice_origin(int step) {
    ivec2 g = ivec2(gl_WorkGroupID.xy);
    return ivec3((g / step) * TILE * step + g % step, gl_WorkGroupID.z);
}

// Loads the tile (lattice points -APRON .. TILE + APRON - 1 of `step`) into workgroup memory.
// Every invocation must call it (barriers). Returns false when no pixel of the group is denoised.
bool load_tile(ivec3 origin, int step) {
    ivec2 size = imageSize(guide_in).xy;
    ivec3 p = origin + ivec3(ivec2(gl_LocalInvocationID.xy) * step, 0);
    if (gl_LocalInvocationIndex == 0u) tile_any = 0u;
    barrier();
    if (all(lessThan(p.xy, size)) && denoised(imageLoad(guide_in, p).w)) tile_any = 1u;
    barrier();
    if (tile_any == 0u) return false;  // the same for the whole group: no barrier follows
    for (uint k = gl_LocalInvocationIndex; k < uint(SIDE * SIDE); k += uint(TILE * TILE)) {
        ivec3 q = origin + ivec3((ivec2(int(k) % SIDE, int(k) / SIDE) - APRON) * step, 0);
        bool inside = all(greaterThanEqual(q.xy, ivec2(0))) && all(lessThan(q.xy, size));
        uvec4 raw = inside ? imageLoad(guide_in, q) : uvec4(0u, 0u, 0u, OUTSIDE);
        tile_shape[k] = vec4(oct_decode(unpackSnorm2x16(raw.y)), uintBitsToFloat(raw.x));
        tile_look[k] = raw.zw;
        tile_value[k] = inside ? stage_value(q) : vec4(0.0);
    }
    barrier();
    return true;
}

// Tile index of the lattice point (dx, dy) steps from this invocation's.
int tile_index(int dx, int dy) {
    ivec2 t = ivec2(gl_LocalInvocationID.xy) + APRON + ivec2(dx, dy);
    return t.y * SIDE + t.x;
}

Guide tile_guide(int k) {
    return Guide(tile_shape[k].w, tile_shape[k].xyz, unpackUnorm4x8(tile_look[k].x).rgb, tile_look[k].y);
}

// The guide (dx, dy) lattice steps away, and whether it exists and shows the centre's effect.
bool tap(int dx, int dy, uint effect, out Guide g) {
    int k = tile_index(dx, dy);
    g = tile_guide(k);
    return tile_look[k].y == effect;
}

struct Centre { Guide g; vec2 grad; float lum; float sigma_l; };

#if DENOISE_STAGE == 1 || DENOISE_STAGE == 4
// Screen-space depth gradient at the centre: per axis the smaller one-sided difference (a
// silhouette next to it does not tilt its plane), 0 where neither neighbour is the same kind.
vec2 depth_gradient(Guide c) {
    vec2 g;
    for (int a = 0; a < 2; a++) {
        ivec2 o = ivec2(a == 0 ? 1 : 0, a == 1 ? 1 : 0);
        Guide fg, bg;
        bool hf = tap(o.x, o.y, c.effect, fg), hb = tap(-o.x, -o.y, c.effect, bg);
        float f = hf ? fg.depth - c.depth : 0.0, b = hb ? c.depth - bg.depth : 0.0;
        g[a] = hf && hb ? (abs(f) < abs(b) ? f : b) : (hf ? f : b);
    }
    return g;
}
#endif

#define LOG2_E 1.4426950408889634
#define NO_WEIGHT -1e30  // a log2 weight whose exp2 is 0

// Edge-stops (SVGF's depth, normal; an albedo term): the log2 of a tap's weight against the
// centre, exp(-z) * cos^sigma_normal * exp(-a), so that the caller takes one exp2 of the sum with
// its luminance term instead of one transcendental per term (the numpy reference multiplies them).
float geometry_log2_weight(Centre c, Guide q, ivec2 offset) {
    float cos_n = dot(c.g.normal, q.normal);
    if (cos_n <= 0.0) return NO_WEIGHT;  // pow(0, sigma_normal): log2 is undefined there
    float tz = abs(c.g.depth - q.depth) /
               (sigma_depth * abs(dot(c.grad, vec2(offset))) + 1e-3 * c.g.depth + 1e-12);
    vec3 da = c.g.albedo - q.albedo;
    float ta = dot(da, da) / (sigma_albedo * sigma_albedo);
    return sigma_normal * log2(cos_n) - (tz + ta) * LOG2_E;
}

#if DENOISE_STAGE == 4
#define OUTLIER_SIDE (2 * DENOISE_OUTLIER_RADIUS + 1)
#define OUTLIER_TAPS (OUTLIER_SIDE * OUTLIER_SIDE - 1)  // the neighbours
// A firefly (one rare bright sample: the light through a glossy lobe's tail) outshines every
// neighbour on its surface, so the à-trous luminance edge-stop shuts those out and it survives
// the filter as a dot. Its luminance is clamped to the mean + DENOISE_OUTLIER_SIGMAS standard
// deviations of its 5x5 neighbours', each weighted by the filter's edge-stops (depth, normal,
// albedo: another surface says nothing), leaving out the brightest neighbour (a second firefly
// beside it would lift the bound over both). 5x5, not 3x3: a penumbra's outer fringe at one
// sample is a few lit pixels among dark ones, and 8 neighbours are often all dark: the clamp then
// darkened the fringe (3x3 took 0.17 % of the denoised pixels' light in the room at one sample,
// 5x5 0.05 %, the fireflies alike). A highlight wider than a pixel has bright neighbours and
// stays; a pixel whose neighbours on its surface weigh less than DENOISE_OUTLIER_MIN_WEIGHT (a
// thin object) stays as it is. A clamped colour keeps its chroma.
vec3 clamp_outlier(Centre c, vec3 illum) {
    float w[OUTLIER_TAPS], l[OUTLIER_TAPS];
    int n = 0, top = -1;
    Guide q;
    for (int dy = -DENOISE_OUTLIER_RADIUS; dy <= DENOISE_OUTLIER_RADIUS; dy++) {
        for (int dx = -DENOISE_OUTLIER_RADIUS; dx <= DENOISE_OUTLIER_RADIUS; dx++) {
            if (dx == 0 && dy == 0) continue;
            bool same = tap(dx, dy, c.g.effect, q);
            w[n] = same ? exp2(geometry_log2_weight(c, q, ivec2(dx, dy))) : 0.0;
            l[n] = luminance(tile_value[tile_index(dx, dy)].rgb);
            // the brightest of the effect's pixels, whatever its weight (a threshold on a weight
            // near 0 would pick by rounding)
            if (same && (top < 0 || l[n] > l[top])) top = n;
            n++;
        }
    }
    float sw = 0.0, s1 = 0.0;
    for (int k = 0; k < OUTLIER_TAPS; k++) {
        if (k == top) continue;
        sw += w[k]; s1 += w[k] * l[k];
    }
    if (sw < DENOISE_OUTLIER_MIN_WEIGHT) return illum;
    float mean = s1 / sw, s2 = 0.0;
    for (int k = 0; k < OUTLIER_TAPS; k++) {
        if (k != top) s2 += w[k] * (l[k] - mean) * (l[k] - mean);  // about the mean: no cancellation
    }
    float bound = mean + DENOISE_OUTLIER_SIGMAS * sqrt(s2 / sw);
    float lum = luminance(illum);
    return lum > bound ? illum * (bound / lum) : illum;
}
#endif
#endif

const float B3[3] = float[3](3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0);  // (1 4 6 4 1) / 16

#if DENOISE_STAGE == 2 || DENOISE_STAGE == 3
// The input's variance at this invocation's pixel blurred 3x3 (Gaussian) over the pixels of the
// centre's effect, from a tile of step 1: a steadier scale for the luminance edge-stop than one
// pixel's estimate.
float blurred_variance(uint effect) {
    float vs = 0.0, vw = 0.0;
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            if (tile_look[tile_index(dx, dy)].y != effect) continue;
            float k = (dx == 0 ? 0.5 : 0.25) * (dy == 0 ? 0.5 : 0.25);
            vs += k * tile_value[tile_index(dx, dy)].a; vw += k;
        }
    }
    return vs / vw;
}
#endif

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
    int step = DENOISE_STAGE == 2 ? step_size : 1;
    ivec3 origin = lattice_origin(step);
    if (!load_tile(origin, step)) return;
    ivec3 p = origin + ivec3(ivec2(gl_LocalInvocationID.xy) * step, 0);
    Centre c;
    c.g = tile_guide(tile_index(0, 0));
    if (!denoised(c.g.effect)) return;  // outside the image (OUTSIDE) or not denoised
    Guide q;
#if DENOISE_STAGE == 4
    c.grad = depth_gradient(c.g);
    // demodulated by the G-buffer's own albedo (the guide's is rounded to 8 bits: edge-stops only)
    imageStore(filter_out, p, vec4(clamp_outlier(c, tile_value[tile_index(0, 0)].rgb), 0.0));
#elif DENOISE_STAGE == 1
    c.grad = depth_gradient(c.g);
    imageStore(gradient_image, p, vec4(c.grad, 0.0, 0.0));
    vec4 accum = imageLoad(color_in, p);
    vec3 illum = tile_value[tile_index(0, 0)].rgb;
    float var;
    if (accum.a >= 4.0) {  // the spread of the samples, over their count: the variance of the mean
        vec2 m = imageLoad(moments_in, p).xy;
        var = max(m.y - m.x * m.x, 0.0) / accum.a;
    } else {  // too few samples: the spread of the neighbours on the same surface
        float sw = 0.0, s1 = 0.0, s2 = 0.0;
        for (int dy = -3; dy <= 3; dy++) {
            for (int dx = -3; dx <= 3; dx++) {
                if (!tap(dx, dy, c.g.effect, q)) continue;
                float w = (dx == 0 && dy == 0) ? 1.0 : exp2(geometry_log2_weight(c, q, ivec2(dx, dy)));
                float l = luminance(tile_value[tile_index(dx, dy)].rgb);
                sw += w; s1 += w * l; s2 += w * l * l;
            }
        }
        s1 /= sw; s2 /= sw;
        var = max(s2 - s1 * s1, 0.0);
    }
    imageStore(filter_out, p, vec4(illum, var));
#elif DENOISE_STAGE == 3
    imageStore(variance_image, p, vec4(blurred_variance(c.g.effect)));
#else
    vec4 centre_value = tile_value[tile_index(0, 0)];
    c.grad = imageLoad(gradient_image, p).xy;
    c.lum = luminance(centre_value.rgb);
    float var = step == 1 ? blurred_variance(c.g.effect) : imageLoad(variance_image, p).x;
    c.sigma_l = sigma_luminance * sqrt(max(var, 0.0)) + 1e-10;
    float log2_per_luminance = LOG2_E / c.sigma_l;
    float w0 = B3[0] * B3[0];
    float sum_w = w0;
    vec3 sum_c = w0 * centre_value.rgb;
    float sum_v = w0 * w0 * centre_value.a;
    for (int dy = -2; dy <= 2; dy++) {
        for (int dx = -2; dx <= 2; dx++) {
            if (dx == 0 && dy == 0) continue;
            if (!tap(dx, dy, c.g.effect, q)) continue;
            vec4 v = tile_value[tile_index(dx, dy)];
            float log2_w = geometry_log2_weight(c, q, ivec2(dx, dy) * step) - abs(c.lum - luminance(v.rgb)) * log2_per_luminance;
            float w = B3[abs(dx)] * B3[abs(dy)] * exp2(log2_w);
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
