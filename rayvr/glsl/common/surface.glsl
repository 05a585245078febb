// A shaded surface point in the G-buffer's terms: what gbuffer_fetch (common/gbuffer.glsl) reads
// back for a pixel and what triangle_surface (common/triangle_surface.glsl) computes for a hit.
#ifndef RAYVR_SURFACE_GLSL
#define RAYVR_SURFACE_GLSL

struct Surface {
    vec3 position;   // scene-local
    float view_depth;
    vec3 normal;
    float roughness;
    vec3 base_color;
    float metallic;
    vec3 emission;
    uint material;
    uint effect;
    uint triangle;
};

#endif
