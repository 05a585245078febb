// The surface a ray hit, in the G-buffer's terms (Surface of common/gbuffer.glsl), so secondary
// hits are shaded exactly like G-buffer pixels. Mirrors the per-pixel work of
// gbuffer/resolve.comp, with the BVH's barycentrics instead of the pixel-ray/plane intersection.
#ifndef RAYVR_RT_HIT_SURFACE_GLSL
#define RAYVR_RT_HIT_SURFACE_GLSL
#include "../common/gbuffer.glsl"
#include "../common/scene.glsl"
#include "../common/color.glsl"
#include "../accel/bvh.glsl"

layout(binding = 7) uniform sampler2DArray base_color_textures;

// Unit geometric normal of scene triangle `tri`, wound v0 -> v1 -> v2.
vec3 triangle_normal(uint tri) {
    TriangleVerts t = scene_triangle(tri);
    return normalize(cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
}

// ng: unit geometric normal, turned to face the incoming ray (the side secondary rays leave from).
Surface surface_at_hit(Hit h, vec3 dir, out vec3 ng) {
    TriangleVerts tv = scene_triangle(h.prim);
    vec3 w = vec3(1.0 - h.uv.x - h.uv.y, h.uv.x, h.uv.y);
    ng = normalize(cross(tv.p[1] - tv.p[0], tv.p[2] - tv.p[0]));
    vec3 ni = w.x * tv.n[0] + w.y * tv.n[1] + w.z * tv.n[2];
    vec3 n = dot(ni, ni) > 1e-20 ? normalize(ni) : ng;
    if (dot(ng, dir) > 0.0) {  // two-sided, as in the resolve
        ng = -ng;
        n = -n;
    }
    uint mi = triangle_material[h.prim];
    Material m = materials[mi];
    vec4 base = m.base_color;
    if (m.texture_layer >= 0) {
        // Finest level: secondary rays carry no ray differentials (yet).
        vec2 uv = w.x * tv.uv[0] + w.y * tv.uv[1] + w.z * tv.uv[2];
        vec4 tex = textureLod(base_color_textures, vec3(uv, float(m.texture_layer)), 0.0);
        base *= vec4(srgb_to_linear(tex.rgb), tex.a);
    }
    Surface s;
    s.position = bvh_hit_point(h);  // from barycentrics: what offset_ray expects
    s.view_depth = h.t;
    s.normal = n;
    s.roughness = m.roughness;
    s.base_color = base.rgb;
    s.metallic = m.metallic;
    s.emission = m.emission.rgb;
    s.material = mi;
    s.effect = m.effect;
    s.triangle = h.prim;
    return s;
}

#endif
