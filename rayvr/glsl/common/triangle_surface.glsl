// The surface of a scene triangle at a point given by barycentric weights: interpolated shading
// normal, material and textured base colour. One function for the G-buffer resolve
// (gbuffer/resolve.comp: primary hits, texture LOD from ray differentials) and for secondary-ray
// hits (rt/hit_surface.glsl: finest level), so both shade the same surface the same way.
#ifndef RAYVR_TRIANGLE_SURFACE_GLSL
#define RAYVR_TRIANGLE_SURFACE_GLSL
#include "surface.glsl"
#include "scene.glsl"
#include "color.glsl"

layout(binding = UNIT_BASE_COLOR_TEXTURES) uniform sampler2DArray base_color_textures;

vec2 triangle_uv(TriangleVerts tv, vec3 w) {
    return w.x * tv.uv[0] + w.y * tv.uv[1] + w.z * tv.uv[2];
}

// Triangle `tri` (vertices tv, geometric normal ng of any length, wound v0 -> v1 -> v2) at weights
// w (of v0, v1, v2), seen along direction d: every Surface field but position and view_depth.
// Two-sided: the normal is turned to face against d (scene.glsl two_sided_normal). Emission is
// seen only on the front face (d against ng) unless the material emits from both (scene.glsl).
// The base colour texture is read at level `lod`.
Surface triangle_surface(uint tri, TriangleVerts tv, vec3 w, vec3 ng, vec3 d, float lod) {
    vec3 ni = w.x * tv.n[0] + w.y * tv.n[1] + w.z * tv.n[2];
    vec3 n = two_sided_normal(ni, ng, d);
    uint mi = triangle_material[tri];
    Material m = materials[mi];
    vec4 base = m.base_color;
    if (m.texture_layer >= 0) {
        vec4 tex = textureLod(base_color_textures, vec3(triangle_uv(tv, w), float(m.texture_layer)), lod);
        base *= vec4(srgb_to_linear(tex.rgb), tex.a);  // textures hold sRGB-encoded colour
    }
    Surface s;
    s.position = vec3(0.0);
    s.view_depth = 0.0;
    s.normal = n;
    s.roughness = m.roughness;
    s.base_color = base.rgb;
    s.metallic = m.metallic;
    s.emission = emits_both_sides(m) || dot(ng, d) < 0.0 ? m.emission.rgb : vec3(0.0);
    s.material = mi;
    s.effect = m.effect;
    s.triangle = tri;
    return s;
}

#endif
