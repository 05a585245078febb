// A tile's conservative frustum (accel/tile_cull.comp writes it: 4 side planes and a far plane,
// n.x <= w) against BVH boxes and triangles, shared by the entry cut (tile_cull.comp) and the tile
// triangle lists (tile_tris.comp). Both tests only cull: every slack errs towards "overlaps".
#ifndef RAYVR_ACCEL_TILE_FRUSTUM_GLSL
#define RAYVR_ACCEL_TILE_FRUSTUM_GLSL
#include "../layout.glsl"  // TILE_SLACK: rayvr/accel/frustum.py SLACK

bool frustum_overlaps(vec4 planes[5], vec3 lo, vec3 hi) {
    vec3 c = 0.5 * (lo + hi), e = 0.5 * (hi - lo);   // an inverted (empty) box has e < 0: culled
    for (int k = 0; k < 5; ++k) {
        vec3 n = planes[k].xyz;
        float m = dot(n, c) - dot(abs(n), e);
        float eps = TILE_SLACK * (dot(abs(n), abs(c) + abs(e)) + abs(planes[k].w));
        if (m > planes[k].w + eps)
            return false;
    }
    return true;
}

// False when the triangle lies wholly outside one plane: no ray of the tile can meet it.
bool frustum_meets_triangle(vec4 planes[5], vec3 a, vec3 b, vec3 c) {
    for (int k = 0; k < 5; ++k) {
        vec3 n = planes[k].xyz;
        float eps = TILE_SLACK * (dot(abs(n), max(max(abs(a), abs(b)), abs(c))) + abs(planes[k].w));
        if (min(min(dot(n, a), dot(n, b)), dot(n, c)) > planes[k].w + eps)
            return false;
    }
    return true;
}
#endif
