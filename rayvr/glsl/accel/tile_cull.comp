#version 430
// Tile frustum culling (HVVR's tile frusta, on the GPU; rayvr/accel/frustum.py): one work group per
// tile of TILE_RAYS consecutive rays. The group bounds its rays with a conservative frustum, then one
// invocation walks the binary BVH against it and writes the tile's entry list: up to TILE_ENTRIES
// children (parent << 1 | side) whose boxes meet the frustum, a cut of the tree under which lies
// every triangle a ray of the tile can hit. Traversal from the list: bvh2.glsl bvh_traverse_entries.
//
// Frustum (the math of frustum.py's tile_frusta, which tests check): c = the normalized mean of
// the rays' unit directions, u, v perpendicular to it; slopes su = (d.u)/(d.c), sv likewise. Planes
// n.x <= w: n = u - max(su) c, -u + min(su) c, v - max(sv) c, -v + min(sv) c, each w the largest n.o
// over the rays' origins (so rays from a lens, or from surface points, are covered), and a far plane
// n = c, w = max(c.o + tmax d.c). Every point o + t d, t >= 0, of every ray satisfies them all.
// Slopes and offsets get a relative slack that covers float rounding. A tile whose directions spread
// over a half-space or more (min d.c <= TILE_MIN_COS) is not culled: its list is the root's children.
// Words per tile: [count, entry 0 .. entry TILE_ENTRIES-1]; count 0 for a tile with no valid ray.
#include "../layout.glsl"
#ifndef TILE_RAYS
#define TILE_RAYS DEFAULT_TILE_RAYS
#define TILE_ENTRIES DEFAULT_TILE_ENTRIES
#endif
#ifndef TILE_ENTRIES_BINDING
#define TILE_ENTRIES_BINDING SSBO_TILE_ENTRIES
#define TILE_PLANES_BINDING SSBO_TILE_PLANES
#endif
#ifndef RAYS_BINDING
#define RAYS_BINDING 10
#endif
layout(local_size_x = TILE_RAYS) in;

#define TILE_CULL_WRITER 1   // declares tile_entries writable itself
#include "bvh.glsl"

#ifndef TILE_MIN_COS
#define TILE_MIN_COS 0.1
#endif
#define TILE_SLACK 1e-5

layout(std430, binding = RAYS_BINDING) readonly restrict buffer Rays { vec4 rays[]; };  // (o, tmin), (d, tmax)
layout(std430, binding = TILE_ENTRIES_BINDING) writeonly restrict buffer Entries { uint tile_entries[]; };
layout(std430, binding = TILE_PLANES_BINDING) writeonly restrict buffer Planes { vec4 tile_planes[]; };  // 5 a tile (tests)

uniform uint ray_count;

shared vec4 red[TILE_RAYS];
shared uint cut[2][TILE_ENTRIES];

// red[0] = op over the group of every invocation's x (op: 0 sum, 1 min, 2 max).
#define REDUCE(x, op) { \
    red[lid] = (x); \
    barrier(); \
    for (uint st = uint(TILE_RAYS) / 2u; st > 0u; st >>= 1u) { \
        if (lid < st) \
            red[lid] = op == 0 ? red[lid] + red[lid + st] : (op == 1 ? min(red[lid], red[lid + st]) \
                                                                     : max(red[lid], red[lid + st])); \
        barrier(); \
    } \
}

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

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint tile = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    uint i = tile * uint(TILE_RAYS) + lid;
    Ray r = Ray(vec3(0.0), 0.0, vec3(0.0), 0.0);
    if (i < ray_count) {
        vec4 a = rays[2u * i], b = rays[2u * i + 1u];
        r = Ray(a.xyz, a.w, b.xyz, b.w);
    }
    bool valid = i < ray_count && bvh_ray_valid(r);
    vec3 dn = valid ? normalize(r.direction) : vec3(0.0);

    REDUCE(vec4(dn, valid ? 1.0 : 0.0), 0)
    vec4 sum = red[0];
    barrier();
    uint base = tile * uint(TILE_ENTRIES + 1);
    vec3 c = length(sum.xyz) > 0.0 ? normalize(sum.xyz) : vec3(0.0, 0.0, 1.0);
    vec3 u = normalize(abs(c.x) < 0.6 ? cross(c, vec3(1.0, 0.0, 0.0)) : cross(c, vec3(0.0, 1.0, 0.0)));
    vec3 v = cross(c, u);
    float dc = dot(dn, c);
    float su = dot(dn, u) / dc, sv = dot(dn, v) / dc;
    const float big = 3.0e38;
    REDUCE(valid ? vec4(dc, su, -su, sv) : vec4(big), 1)
    vec4 mins = red[0];
    barrier();
    float far = valid ? dot(c, r.origin) + r.tmax * dot(c, r.direction) : -big;
    REDUCE(valid ? vec4(sv, far, dot(abs(r.origin), vec3(1.0)), 0.0) : vec4(-big), 2)
    vec4 maxs = red[0];
    barrier();
    float slack_o = TILE_SLACK * maxs.z;
    vec3 n[4] = vec3[4](u - (-mins.z + TILE_SLACK * (1.0 + abs(mins.z))) * c,
                        -u + (mins.y - TILE_SLACK * (1.0 + abs(mins.y))) * c,
                        v - (maxs.x + TILE_SLACK * (1.0 + abs(maxs.x))) * c,
                        -v + (mins.w - TILE_SLACK * (1.0 + abs(mins.w))) * c);
    REDUCE(valid ? vec4(dot(n[0], r.origin), dot(n[1], r.origin), dot(n[2], r.origin), dot(n[3], r.origin))
                 : vec4(-big), 2)
    vec4 w = red[0];
    if (lid != 0u)
        return;
    bool fallback = !(mins.x > TILE_MIN_COS);    // also NaN
    vec4 planes[5];
    for (int k = 0; k < 4; ++k)
        planes[k] = vec4(n[k], w[k] + TILE_SLACK * length(n[k]) * maxs.z + slack_o);
    planes[4] = vec4(c, maxs.y + TILE_SLACK * (abs(maxs.y) + maxs.z));
    for (int k = 0; k < 5; ++k)
        tile_planes[5u * tile + uint(k)] = sum.w == 0.0 ? vec4(0.0) : (fallback ? vec4(0.0, 0.0, 0.0, 1.0) : planes[k]);
    if (sum.w == 0.0) {              // no valid ray: nothing to trace
        tile_entries[base] = 0u;
        return;
    }
    // The cut: start at the root's children, then sweep the list left to right opening internal
    // entries into their children that meet the frustum while the list has room; stop when a sweep
    // opens nothing. Left-to-right order is kept, so entries stay in tree order.
    int count = 0, cur = 0;
    for (int side = 0; side < 2; ++side) {
        vec3 lo, hi;
        bvh2_child_box(bvh_nodes[0], bvh_nodes[1], bvh_nodes[2], side, lo, hi);
        if (fallback || frustum_overlaps(planes, lo, hi))
            cut[0][count++] = uint(side);
    }
    bool opened = !fallback;
    while (opened) {
        opened = false;
        int out_n = 0;
        for (int k = 0; k < count; ++k) {
            uint e = cut[cur][k];
            int parent = int(e >> 1u), side = int(e & 1u);
            ivec4 m = floatBitsToInt(bvh_nodes[4 * parent + 3]);
            int index = side == 0 ? m.x : m.y, cnt = side == 0 ? m.z : m.w;
            // room: this entry's slot plus one more, and one slot for each entry still to copy
            if (cnt > 0 || out_n + 2 + (count - k - 1) > TILE_ENTRIES) {
                cut[1 - cur][out_n++] = e;
                continue;
            }
            opened = true;
            for (int cs = 0; cs < 2; ++cs) {
                vec3 lo, hi;
                bvh2_child_box(bvh_nodes[4 * index], bvh_nodes[4 * index + 1], bvh_nodes[4 * index + 2], cs, lo, hi);
                if (frustum_overlaps(planes, lo, hi))
                    cut[1 - cur][out_n++] = (uint(index) << 1u) | uint(cs);
            }
        }
        count = out_n;
        cur = 1 - cur;
    }
    tile_entries[base] = uint(count);
    for (int k = 0; k < count; ++k)
        tile_entries[base + 1u + uint(k)] = cut[cur][k];
}
