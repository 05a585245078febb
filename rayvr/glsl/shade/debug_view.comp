#version 430
// Debug views of G-buffer channels, written straight to the 8-bit output.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/gbuffer.glsl"
#include "../common/scene.glsl"
#include "../common/color.glsl"

layout(rgba8, binding = IMAGE_LDR) uniform writeonly image2DArray ldr_out;
uniform int view;         // VIEW_* (rayvr/gl/gpu_layout.py DEBUG_VIEWS)
uniform vec2 depth_range; // view-depth range mapped to black..white (log scale)

vec3 hash_color(uint x) {
    x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
    return vec3(x & 255u, (x >> 8) & 255u, (x >> 16) & 255u) / 255.0;
}

// One colour per effect ID of the ladder's first rungs (raster .. photon); plugins get a hashed one.
const vec3 EFFECT_COLORS[7] = vec3[7](
    vec3(0.55, 0.55, 0.55), vec3(0.25, 0.45, 0.95), vec3(0.2, 0.8, 0.8), vec3(0.95, 0.85, 0.2),
    vec3(0.95, 0.5, 0.15), vec3(0.85, 0.2, 0.6), vec3(0.5, 0.9, 0.3));

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p.xy, imageSize(ldr_out).xy))) return;
    Surface s = gbuffer_fetch(p);
    vec3 c = vec3(0.0);
    bool hit = s.triangle != NO_HIT;
    if (hit) {
        if (view == VIEW_DEPTH) {  // depth: log view depth, near white
            float t = (log(s.view_depth) - log(depth_range.x)) / max(log(depth_range.y) - log(depth_range.x), 1e-6);
            c = vec3(1.0 - clamp(t, 0.0, 1.0));
        } else if (view == VIEW_NORMAL) { c = s.normal * 0.5 + 0.5; }
        else if (view == VIEW_ALBEDO) { c = linear_to_srgb(s.base_color); }
        else if (view == VIEW_ROUGHNESS) { c = vec3(s.roughness); }
        else if (view == VIEW_METALLIC) { c = vec3(s.metallic); }
        else if (view == VIEW_EMISSION) { c = linear_to_srgb(tonemap(s.emission, TONEMAP_ACES)); }
        else if (view == VIEW_MATERIAL) { c = hash_color(s.material + 1u); }
        else if (view == VIEW_EFFECT) { c = s.effect < 7u ? EFFECT_COLORS[s.effect] : hash_color(s.effect); }
        else if (view == VIEW_TRIANGLE) { c = hash_color(s.triangle + 1u); }
        else if (view == VIEW_POSITION) { c = fract(s.position); }
    }
    imageStore(ldr_out, p, vec4(c, 1.0));
}
