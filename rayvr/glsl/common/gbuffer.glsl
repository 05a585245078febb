// Reading the layered G-buffer (layer = eye) from compute passes.
// Channel table: rayvr/gl/gpu_layout.py (CHANNELS); units from the generated layout.glsl.
#ifndef RAYVR_GBUFFER_GLSL
#define RAYVR_GBUFFER_GLSL
#include "surface.glsl"
#include "../layout.glsl"

layout(binding = GB_UNIT_DEPTH) uniform sampler2DArray gb_depth;      // reversed-Z depth
layout(binding = GB_UNIT_POSITION) uniform sampler2DArray gb_position;   // xyz scene-local, w view depth
layout(binding = GB_UNIT_NORMAL) uniform sampler2DArray gb_normal;     // xyz world normal, w roughness
layout(binding = GB_UNIT_ALBEDO) uniform sampler2DArray gb_albedo;     // rgb base colour, a metallic
layout(binding = GB_UNIT_EMISSION) uniform sampler2DArray gb_emission;   // rgb emitted radiance
layout(binding = GB_UNIT_MATERIAL) uniform usampler2DArray gb_material;  // x material index, y effect ID
layout(binding = GB_UNIT_TRIANGLE) uniform usampler2DArray gb_triangle;  // x triangle ID

Surface gbuffer_fetch(ivec3 p) {
    Surface s;
    vec4 a = texelFetch(gb_position, p, 0);
    vec4 b = texelFetch(gb_normal, p, 0);
    vec4 c = texelFetch(gb_albedo, p, 0);
    uvec2 m = texelFetch(gb_material, p, 0).xy;
    s.position = a.xyz; s.view_depth = a.w;
    // Renormalised: the half-float channel rounds (llvmpipe truncates) and |n| < 1 dims sharp
    // highlights (9.5 % on the room's gold sphere against the numpy reference).
    s.normal = b.xyz * inversesqrt(max(dot(b.xyz, b.xyz), 1e-30)); s.roughness = b.w;
    s.base_color = c.rgb; s.metallic = c.a;
    s.emission = texelFetch(gb_emission, p, 0).rgb;
    s.material = m.x; s.effect = m.y;
    s.triangle = texelFetch(gb_triangle, p, 0).x;
    return s;
}

#endif
