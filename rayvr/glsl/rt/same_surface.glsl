// Which sub-rays of a pixel the MSAA merge (rt/primary.comp, rt/tile_samples.comp) shades as one
// entry. MSAA_MERGE_SURFACES 0: sub-rays on one triangle. 1 (shading_merge "surface"): also
// sub-rays on neighbouring triangles of one smooth surface (rayvr/scene/surfaces.py, per triangle
// in triangle_surface) whose distances differ by at most SURFACE_DEPTH_TOLERANCE of the larger
// (a torus's front and its own far side behind it stay apart). An entry is the sub-rays linked
// so, directly or through others of the pixel (the link alone is not transitive): never more
// entries than triangles. The numpy twin is frame/passes/primary_rays.py msaa_lists.
#ifndef RAYVR_RT_SAME_SURFACE_GLSL
#define RAYVR_RT_SAME_SURFACE_GLSL
#include "../layout.glsl"
#ifndef MSAA_MERGE_SURFACES
#define MSAA_MERGE_SURFACES 0
#endif
#if MSAA_MERGE_SURFACES
layout(std430, binding = SSBO_TRIANGLE_SURFACE) readonly buffer TriangleSurfaces { uint triangle_surface[]; };
#endif

// The surface of a sub-ray's hit (BVH_MISS: the background, a surface of its own).
uint surface_of(uint tri) {
#if MSAA_MERGE_SURFACES
    return tri == BVH_MISS ? BVH_MISS : triangle_surface[tri];
#else
    return tri;
#endif
}

// Whether two sub-rays' hits (triangle, its surface, distance) are linked: shaded as one.
bool same_surface(uint tri_a, uint surface_a, float t_a, uint tri_b, uint surface_b, float t_b) {
    if (tri_a == tri_b) return true;
#if MSAA_MERGE_SURFACES
    return surface_a == surface_b && surface_a != BVH_MISS &&
           abs(t_a - t_b) <= SURFACE_DEPTH_TOLERANCE * max(t_a, t_b);
#else
    return false;
#endif
}
#endif
