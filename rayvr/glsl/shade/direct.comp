#version 430
// `raster` shading: direct light from the G-buffer for every covered pixel of every eye.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/gbuffer.glsl"
#include "../common/lighting.glsl"
#include "../common/camera.glsl"
#include "../common/round_skip.glsl"
#ifdef STEREO_REUSE
#include "../stereo/reuse.glsl"
#endif

layout(rgba16f, binding = IMAGE_HDR) uniform writeonly image2DArray hdr_out;
uniform vec3 ambient;           // constant ambient radiance (stands in for indirect light)
uniform vec3 background;
uniform uint traced_effects;    // bit e set: effect e's own passes shade those pixels

void main() {
    ivec3 p = round_pixel();  // (an MSAA round: over its listed tiles)
    if (any(greaterThanEqual(p.xy, imageSize(hdr_out).xy))) return;
    if (round_skips(p)) return;  // adds nothing to the frame (MSAA round)
#ifdef STEREO_REUSE
    if (reuse_taken(p, imageSize(hdr_out).x)) return;  // takes the left eye's shading (stereo/reuse_copy.comp)
#endif
    Surface s = gbuffer_fetch(p);
    if (s.triangle != NO_HIT && s.effect < 32u && ((traced_effects >> s.effect) & 1u) != 0u) return;
    vec3 color;
    if (s.triangle == NO_HIT) {
        color = background;
    } else {
        vec3 v = normalize(eye_position[p.z] - s.position);
        color = s.emission + direct_light(s.position, s.normal, v, s.base_color, s.metallic, s.roughness)
              + ambient * s.base_color;  // constant environment light, diffuse and specular alike
    }
    imageStore(hdr_out, p, vec4(color, 1.0));
}
