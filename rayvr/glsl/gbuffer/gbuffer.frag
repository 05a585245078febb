#version 430
// G-buffer fragment stage: writes every channel of rayvr/gbuffer.py's CHANNELS table.
#include "../common/scene.glsl"
#include "../common/color.glsl"

in VertexData {
    vec3 position;
    vec3 normal;
    vec2 uv;
    float view_depth;
} fs_in;

layout(binding = 0) uniform sampler2DArray base_color_textures;

layout(location = 0) out vec4 out_position;   // xyz scene-local, w view depth
layout(location = 1) out vec4 out_normal;     // xyz world normal (facing the viewer), w roughness
layout(location = 2) out vec4 out_albedo;     // rgb base colour, a metallic
layout(location = 3) out vec4 out_emission;   // rgb emitted radiance
layout(location = 4) out uvec2 out_material;  // material index, effect ID
layout(location = 5) out uint out_triangle;   // triangle ID

void main() {
    uint tri = uint(gl_PrimitiveID);
    uint mi = triangle_material[tri];
    Material m = materials[mi];
    vec4 base = m.base_color;
    if (m.texture_layer >= 0) {
        vec4 t = texture(base_color_textures, vec3(fs_in.uv, float(m.texture_layer)));
        base *= vec4(srgb_to_linear(t.rgb), t.a);  // textures hold sRGB-encoded colour
    }
    vec3 n = normalize(fs_in.normal);
    // Two-sided shading: the normal faces the side the eye sees.
    if (!gl_FrontFacing) n = -n;
    out_position = vec4(fs_in.position, fs_in.view_depth);
    out_normal = vec4(n, m.roughness);
    out_albedo = vec4(base.rgb, m.metallic);
    out_emission = vec4(m.emission.rgb, 1.0);
    out_material = uvec2(mi, m.effect);
    out_triangle = tri;
}
