// Scene data shared by raster and compute passes (std430; layouts mirror rayvr/scene/gpu_scene.py).
#ifndef RAYVR_SCENE_GLSL
#define RAYVR_SCENE_GLSL
#include "../layout.glsl"

struct Material {
    vec4 base_color;      // linear RGBA
    vec4 emission;        // rgb radiance, w 1: emits from both faces (emits_both_sides)
    float metallic;
    float roughness;
    int texture_layer;    // -1: no base-colour texture
    uint effect;          // effect-ladder ID from the material config
    uvec4 params[MATERIAL_PARAM_WORDS / 4];  // the effect's parameters (rayvr/frame/effect_registry.py pack_params)
};

struct Light {
    vec4 position_kind;   // xyz scene-local position (rect: centre), w kind
    vec4 radiance;        // rgb colour * intensity; w: its probability of a pick (scene/light_selection.py)
    vec4 direction;       // directional: direction light travels; w: the picks' running sum up to it
    vec4 u;               // rect: half-edge vectors; w 1: emits on both sides (light_two_sided)
    vec4 v;
};

layout(std430, binding = SSBO_TRIANGLE_MATERIAL) readonly buffer TriangleMaterials { uint triangle_material[]; };
layout(std430, binding = SSBO_MATERIALS) readonly buffer Materials { Material materials[]; };
layout(std430, binding = SSBO_LIGHTS) readonly buffer Lights { Light lights[]; };
layout(std430, binding = SSBO_VERTICES) readonly buffer Vertices { float vertex_data[]; };
layout(std430, binding = SSBO_INDICES) readonly buffer Indices { uint index_data[]; };

// Emission leaves a triangle's front face (the side its winding's normal points to) only, unless
// the material is double-sided (rayvr/scene/loader.py Material.double_sided); rect lights alike.
bool emits_both_sides(Material m) { return m.emission.w > 0.5; }
bool light_two_sided(Light li) { return li.u.w > 0.5; }

// --light-picks (rayvr/scene/light_selection.py): 0, every light lights every surface; K > 0, the
// traced effects draw K lights per surface by power. Set by the wavefront passes.
uniform int light_picks;

// The light a uniform u in [0, 1) draws: the first whose running sum exceeds u (the last's is 1).
int pick_light(float u) {
    int lo = 0, hi = lights.length() - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (lights[mid].direction.w > u) hi = mid; else lo = mid + 1;
    }
    return lo;
}

// Light i's share of its surface's light samples: K x its probability with picks, 1 without.
float light_pick_pdf(int i) { return light_picks > 0 ? float(light_picks) * lights[i].radiance.w : 1.0; }

// Parameter `slot` of material m's effect (PARAM_<EFFECT>_<NAME>, or PARAM_<NAME> in an effect's
// own shaders): ints as int32, floats as float32 bits.
uint material_param_bits(uint m, int slot) { return materials[m].params[slot >> 2][slot & 3]; }
int material_param_int(uint m, int slot) { return int(material_param_bits(m, slot)); }
float material_param_float(uint m, int slot) { return uintBitsToFloat(material_param_bits(m, slot)); }

struct TriangleVerts { vec3 p[3]; vec3 n[3]; vec2 uv[3]; };

void scene_vertex(uint tri, uint k, out vec3 p, out vec3 n, out vec2 uv) {
    uint b = index_data[3u * tri + k] * uint(VERTEX_FLOATS);
    p = vec3(vertex_data[b], vertex_data[b + 1u], vertex_data[b + 2u]);
    n = vec3(vertex_data[b + 3u], vertex_data[b + 4u], vertex_data[b + 5u]);
    uv = vec2(vertex_data[b + 6u], vertex_data[b + 7u]);
}

// The three vertices written with constant indices: filled in a loop, NVIDIA kept the struct's
// arrays in local memory in photon/trace.comp (its NV assembly).
TriangleVerts scene_triangle(uint tri) {
    TriangleVerts t;
    scene_vertex(tri, 0u, t.p[0], t.n[0], t.uv[0]);
    scene_vertex(tri, 1u, t.p[1], t.n[1], t.uv[1]);
    scene_vertex(tri, 2u, t.p[2], t.n[2], t.uv[2]);
    return t;
}

// The geometric normal (v1 - v0) x (v2 - v0) of a triangle, not unit (twice its area long): it
// points to the front face, the side of the winding v0 -> v1 -> v2. Every shader that needs a
// triangle's plane takes it from here (the numpy twin: accel/quadtree.py geometric_normals).
vec3 triangle_normal(TriangleVerts tv) {
    return cross(tv.p[1] - tv.p[0], tv.p[2] - tv.p[0]);
}

// Shading normal of a two-sided surface from the interpolated vertex normal ni (any length; zero:
// the geometric normal ng): turned to ng's side first (a file's normals may be wound against its
// triangles), then to face against the view direction d. Mitsuba's `twosided` shades alike.
vec3 two_sided_normal(vec3 ni, vec3 ng, vec3 d) {
    vec3 n = dot(ni, ni) > 1e-20 ? normalize(ni) : normalize(ng);
    if (dot(n, ng) < 0.0) n = -n;
    return dot(ng, d) > 0.0 ? -n : n;
}

#endif
