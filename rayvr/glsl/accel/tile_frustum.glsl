// A tile's conservative frustum (accel/tile_cull.comp writes it: 4 side planes and a far plane,
// n.x <= w) against BVH boxes and triangles, shared by the entry cut (tile_cull.comp) and the tile
// triangle lists (tile_tris.comp). Both tests only cull: every slack errs towards "overlaps".
#ifndef RAYVR_ACCEL_TILE_FRUSTUM_GLSL
#define RAYVR_ACCEL_TILE_FRUSTUM_GLSL
#include "../layout.glsl"  // TILE_SLACK: rayvr/accel/frustum.py SLACK

// The frame (u, v) about a beam's unit central direction c in which its direction slopes are taken:
// one definition for the tile cull that writes slopes, the block cull that reads them, and the sample
// testing's 2D edge functions.
void beam_frame(vec3 c, out vec3 u, out vec3 v) {
    u = normalize(abs(c.x) < 0.6 ? cross(c, vec3(1.0, 0.0, 0.0)) : cross(c, vec3(0.0, 1.0, 0.0)));
    v = cross(c, u);
}

// Direction slopes (min su, max su, min sv, max sv) about c, widened outwards by the rounding slack.
vec4 widened_slopes(vec4 s) {
    vec4 e = TILE_SLACK * (1.0 + abs(s));
    return s + vec4(-e.x, e.y, -e.z, e.w);
}

// The normals of a beam's four side planes n.x <= w for widened slopes s about c in the frame (u, v):
// every direction c + su u + sv v with su, sv inside s has n.d <= 0.
void beam_side_normals(vec3 c, vec3 u, vec3 v, vec4 s, out vec3 n[4]) {
    n[0] = u - s.y * c;
    n[1] = -u + s.x * c;
    n[2] = v - s.w * c;
    n[3] = -v + s.z * c;
}

// Adds ray (o, d, tmax) to a beam's extremes about c in the frame (u, v), the planes' inputs:
// mins = (least cosine of d to c, min su, -max su, min sv), maxs = (max sv, the largest far c.x =
// c.o + tmax d.c, the largest |o| summed over axes, the largest reach tmax |d|).
void beam_add_ray(vec3 c, vec3 u, vec3 v, vec3 o, vec3 d, float tmax, inout vec4 mins, inout vec4 maxs) {
    vec3 dn = normalize(d);
    float dc = dot(dn, c);
    float su = dot(dn, u) / dc, sv = dot(dn, v) / dc;
    mins = min(mins, vec4(dc, su, -su, sv));
    maxs = max(maxs, vec4(sv, dot(c, o) + tmax * dot(c, d), dot(abs(o), vec3(1.0)), tmax * length(d)));
}

// The side planes' offsets w (n.x <= w) over a box of ray origins: the largest n.o in the box.
vec4 box_offsets(vec3 n[4], vec3 lo, vec3 hi) {
    vec3 c = 0.5 * (lo + hi), e = 0.5 * (hi - lo);
    return vec4(dot(n[0], c) + dot(abs(n[0]), e), dot(n[1], c) + dot(abs(n[1]), e),
                dot(n[2], c) + dot(abs(n[2]), e), dot(n[3], c) + dot(abs(n[3]), e));
}

// A beam's five planes from its side normals n with their offsets w, its central direction c and
// maxs = (-, the largest far c.x = c.o + tmax d.c, the largest |o| summed over axes, -), each offset
// with the rounding slack.
void beam_planes(vec3 c, vec3 n[4], vec4 w, vec4 maxs, out vec4 planes[5]) {
    float slack_o = TILE_SLACK * maxs.z;
    for (int k = 0; k < 4; ++k)
        planes[k] = vec4(n[k], w[k] + TILE_SLACK * length(n[k]) * maxs.z + slack_o);
    planes[4] = vec4(c, maxs.y + TILE_SLACK * (abs(maxs.y) + maxs.z));
}

bool frustum_overlaps(vec4 planes[5], vec3 lo, vec3 hi) {
    // An inverted box is an empty child slot (a one-leaf BVH's right child, rayvr/accel/bvh.py
    // EMPTY_LO/EMPTY_HI): it meets nothing. Its extent (+-3e38) overflows the test below to +-inf
    // (or NaN), which passes every plane, and a cut that kept it would open it back into the root
    // forever, as its count 0 reads as an internal node at index 0.
    if (any(greaterThan(lo, hi)))
        return false;
    vec3 c = 0.5 * (lo + hi), e = 0.5 * (hi - lo);
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
