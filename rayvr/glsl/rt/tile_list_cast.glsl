// Primary rays against their tile's triangle list (accel/tile_tris.comp; HVVR's per-sub-sample
// intersection): the workgroup, whose pixels all lie in one frame tile, loads the list PRIMARY_GROUP
// triangles at a time into workgroup memory and every invocation tests its ray against them with
// the exact test of the BVH leaves (accel/bvh.glsl bvh_test_triangle): the same triangle and
// distance as per-ray traversal, since the list holds every triangle of the tile's frustum and the
// tie rule makes hits independent of the order.
//
// Two filters keep most triangles from the exact test, both conservative:
//   - the list is sorted by a lower bound of c.x over each triangle (c: the tile's central
//     direction); a ray stops once that bound passes its reach, c.x of its points up to its
//     closest hit (as bvh2.glsl bvh_traverse_entries does with boxes), and the group stops loading
//     once every ray has;
//   - when every ray of the group leaves one origin (all camera models but thin-lens), each
//     triangle's three edge planes through that origin are made once per load, and a ray whose
//     direction lies outside one of them by more than the rounding bound (EDGE_SLACK times the
//     edge's vertex distances) cannot hit it: 3 dot products instead of the exact test. The
//     triangle is then a cone from the origin: d = aA + bB + cC with a, b, c >= 0 for a hit,
//     and the plane of edge AB gives c times the triple product [A B C].
// A tile whose list overflowed (TILE_OVERFLOW) is cast by another program (rt/primary.comp
// TILE_LIST_PART 2), per ray from its entries: the walk's registers would slow the list path.
//
// Two casts share the loads: cast_tile_list, one invocation per ray (the 1x and SSAA casts), and
// for the MSAA trace (MSAA_PIXEL_LISTS) cast_tile_list_pixel, one invocation per pixel testing all its sub-rays (HVVR's
// per-sample kernel): a triangle is fetched from workgroup memory once for the pixel, and a third
// filter, the pixel's cone of sub-ray directions against the three edge planes, rejects most
// triangles for all the pixel's sub-rays at once.
#ifndef RAYVR_RT_TILE_LIST_CAST_GLSL
#define RAYVR_RT_TILE_LIST_CAST_GLSL


shared vec4 list_tri[3][PRIMARY_GROUP];    // the load's vertices (a.w: the original ID bits)
shared vec4 list_edge[3][PRIMARY_GROUP];   // edge planes through the group's origin, w: their slack
shared vec3 list_edge_length[PRIMARY_GROUP];  // |xyz| of the three planes (the pixel cone's test)
shared uint list_slot[PRIMARY_GROUP];
shared float list_key[PRIMARY_GROUP];
shared uint list_more[2];                  // some ray still needs the next load (by parity)
shared uint list_leader;
shared uint list_one_origin;
shared vec3 list_origin;

// The largest list key (a lower bound of c.x over its triangle) a ray whose closest hit so far is at
// t can still meet: c.x of its points up to t, with the rounding slack.
float list_reach(float co, float cd, float t) {
    return co + t * cd + TILE_SLACK * (abs(co) + abs(t * cd));
}

// The group's common origin: `origin` of the first invocation with a live ray, in list_origin;
// list_one_origin stays 1 when every live invocation has it (and `one_origin`: all its own rays
// leave from `origin`), the edge filter's condition. Called by every invocation.
void list_find_origin(bool live, vec3 origin, bool one_origin) {
    uint lid = gl_LocalInvocationIndex;
    if (lid == 0u) {
        list_leader = 0xFFFFFFFFu;
        list_one_origin = 1u;
    }
    barrier();
    if (live)
        atomicMin(list_leader, lid);
    barrier();
    if (lid == list_leader)
        list_origin = origin;
    barrier();
    if (live && (!one_origin || any(notEqual(origin, list_origin))))
        list_one_origin = 0u;
    barrier();
}

// Load `base` of the tile's list (at `head`, n triangles) into workgroup memory, one triangle an
// invocation, with its edge planes through `origin` when `edges`; clears this load's list_more and
// waits for the whole group.
void list_load(uint head, uint base, uint n, uint load, vec3 origin, bool edges) {
    uint lid = gl_LocalInvocationIndex, k = base + lid;
    if (k < n) {
        uvec2 e = tile_tris[head + 1u + k];
        vec4 a = bvh_tris[3u * e.x], b = bvh_tris[3u * e.x + 1u], d = bvh_tris[3u * e.x + 2u];
        list_tri[0][lid] = a;
        list_tri[1][lid] = b;
        list_tri[2][lid] = d;
        list_slot[lid] = e.x;
        list_key[lid] = uintBitsToFloat(e.y);
        // Edge planes (xyz) with their slack (w): a ray passes where dot(xyz, d) + w |d| >= 0 for
        // all three. Zero planes (no common origin; a triangle nearly edge-on to the origin, whose
        // triple product's sign is not sure) pass every ray.
        vec3 A = a.xyz - origin, B = b.xyz - origin, C = d.xyz - origin;
        vec3 ab = cross(A, B), bc = cross(B, C), ca = cross(C, A);
        float triple = dot(ab, C), la = length(A), lb = length(B), lc = length(C);
        float sg = edges && abs(triple) > EDGE_SLACK * la * lb * lc ? sign(triple) : 0.0;
        list_edge[0][lid] = vec4(sg * ab, abs(sg) * EDGE_SLACK * la * lb);
        list_edge[1][lid] = vec4(sg * bc, abs(sg) * EDGE_SLACK * lb * lc);
        list_edge[2][lid] = vec4(sg * ca, abs(sg) * EDGE_SLACK * lc * la);
        list_edge_length[lid] = abs(sg) * vec3(length(ab), length(bc), length(ca));
    }
    if (lid == 0u)
        list_more[load & 1u] = 0u;
    barrier();
}

// The edge filter for one ray direction d (|d| = dlen): false when d lies outside one of triangle
// j's planes by more than their slack (a NaN passes: the exact test decides).
bool list_edges_pass(uint j, vec3 d, float dlen) {
    // one branch for the three planes (no short-circuit: their loads overlap)
    vec4 e0 = list_edge[0][j], e1 = list_edge[1][j], e2 = list_edge[2][j];
    float inside = min(min(dot(e0.xyz, d) + e0.w * dlen, dot(e1.xyz, d) + e1.w * dlen), dot(e2.xyz, d) + e2.w * dlen);
    return !(inside < 0.0);
}

// After a load's tests: whether a ray of this reach needs the next load (sets list_more), then the
// group's answer (uniform).
bool list_next(uint head, uint base, uint n, uint load, bool live, float reach) {
    if (live && base + uint(PRIMARY_GROUP) < n &&
        !(uintBitsToFloat(tile_tris[head + 1u + base + uint(PRIMARY_GROUP)].y) > reach))
        list_more[load & 1u] = 1u;
    barrier();
    return list_more[load & 1u] != 0u;
}

void cast_tile_list(Ray r, uint tile, bool valid, inout Hit h) {
    uint head = tile * uint(TILE_TRIS + 1);
    RayShear s;
    vec3 inv;
    Hit hit;
    bool live = valid && bvh_begin(r, hit, s, inv);
    if (valid)
        h = hit;   // a valid ray that traces nothing is a miss at tmax, as trace_closest makes it
    uint n = tile_tris[head].x;   // not TILE_OVERFLOW: those tiles are rt/primary.comp's TILE_LIST_PART 2
    list_find_origin(live, r.origin, true);
    bool edges = list_one_origin != 0u;
    vec3 origin = list_origin;
    vec3 c = tile_planes[5u * tile + 4u].xyz;
    float co = dot(c, r.origin), cd = dot(c, r.direction), dlen = length(r.direction);
    uint load = 0u;
    for (uint base = 0u; base < n; base += uint(PRIMARY_GROUP), ++load) {
        list_load(head, base, n, load, origin, edges);
        uint m = min(uint(PRIMARY_GROUP), n - base);
        float reach = list_reach(co, cd, h.t);
        if (live) {
            for (uint j = 0u; j < m; ++j) {
                if (list_key[j] > reach)
                    break;   // sorted: every later triangle lies beyond too
                if (list_edges_pass(j, r.direction, dlen) &&
                    bvh_test_triangle(s, list_slot[j], list_tri[0][j], list_tri[1][j], list_tri[2][j], r.tmin, h))
                    reach = list_reach(co, cd, h.t);
            }
        }
        if (!list_next(head, base, n, load, live, reach))
            break;   // uniform: no ray of the group needs the next load
    }
}

#if PRIMARY_MODE == 1 && MSAA_PIXEL_LISTS
// One invocation per pixel (MSAA_PIXEL_LISTS): sub_dir holds the pixel's sub-ray directions beside
// its hits in sub_tri / sub_t (rt/primary.comp, entries base .. base + CAMERA_SUBSAMPLES - 1).
shared vec3 sub_dir[MSAA_SUBRAYS];

// The pixel's reach: the largest of its live sub-rays' (bits of `live`), which share origin term co.
float pixel_reach(uint base, uint live, float co, vec3 c) {
    float reach = -3.0e38;
    for (uint m = live; m != 0u; m &= m - 1u) {
        uint i = uint(findLSB(m));
        reach = max(reach, list_reach(co, dot(c, sub_dir[base + i]), sub_t[base + i]));
    }
    return reach;
}

// The closest hit of every sub-ray of pixel p (its CAMERA_SUBSAMPLES rays, as cast_primary casts
// them) against its tile's list, into sub_tri / sub_t[base ..]: the same triangles and distances as
// one invocation per sub-ray. Called by every invocation of the group.
void cast_tile_list_pixel(ivec3 p, ivec2 size, bool inside, uint tile, uint base) {
    uint head = tile * uint(TILE_TRIS + 1), n = tile_tris[head].x;
    vec2 pixel = vec2(p.xy) + 0.5;
    uint live = 0u;               // sub-rays that trace (bit i: sub-ray i)
    bool one_origin = true;       // every live sub-ray leaves from o0 (all camera models but thin-lens)
    vec3 o0 = vec3(0.0), dsum = vec3(0.0);
    for (uint i = 0u; i < uint(CAMERA_SUBSAMPLES); ++i) {
        vec3 o, d = vec3(0.0);
        Hit h;
        h.prim = BVH_MISS;
        h.t = 0.0;
        if (inside && camera_subray(p.z, pixel, vec2(size), i, o, d)) {
            RayShear s;
            vec3 inv;
            if (bvh_begin(primary_ray(p.z, o, d), h, s, inv)) {
                if (live == 0u) o0 = o;
                one_origin = one_origin && all(equal(o, o0));
                live |= 1u << i;
                dsum += normalize(d);
            }
        }
        sub_tri[base + i] = h.prim;
        sub_t[base + i] = h.t;
        sub_dir[base + i] = d;
    }
    // The pixel's cone: unit axis a, and R >= |d/|d| - a| for every live sub-ray (with the margin of
    // the test's own rounding).
    vec3 a = live != 0u ? normalize(dsum) : vec3(0.0, 0.0, 1.0);
    float R = 0.0;
    for (uint m = live; m != 0u; m &= m - 1u)
        R = max(R, length(normalize(sub_dir[base + uint(findLSB(m))]) - a));
    R += EDGE_SLACK;
    list_find_origin(live != 0u, o0, one_origin);
    bool edges = list_one_origin != 0u;
    vec3 origin = list_origin;
    vec3 c = tile_planes[5u * tile + 4u].xyz;
    float co = dot(c, o0);
    uint load = 0u;
    for (uint b = 0u; b < n; b += uint(PRIMARY_GROUP), ++load) {
        list_load(head, b, n, load, origin, edges);
        uint m = min(uint(PRIMARY_GROUP), n - b);
        // without one origin per pixel the keys' bound is not kept per sub-ray: no early stop
        float reach = one_origin ? pixel_reach(base, live, co, c) : 3.0e38;
        if (live != 0u) {
            for (uint j = 0u; j < m; ++j) {
                if (list_key[j] > reach)
                    break;   // sorted: every later triangle lies beyond every sub-ray's hit
                // The cone: a sub-ray d (unit) passes plane e where dot(e, d) + w >= 0, and
                // dot(e, d) <= dot(e, a) + |e| R: below that for one plane, no sub-ray passes.
                vec3 len = list_edge_length[j];
                if (edges && min(min(dot(list_edge[0][j].xyz, a) + len.x * R + list_edge[0][j].w,
                                     dot(list_edge[1][j].xyz, a) + len.y * R + list_edge[1][j].w),
                                 dot(list_edge[2][j].xyz, a) + len.z * R + list_edge[2][j].w) < 0.0)
                    continue;
                bool hit = false;
                for (uint mm = live; mm != 0u; mm &= mm - 1u) {
                    uint i = uint(findLSB(mm));
                    vec3 d = sub_dir[base + i];
                    if (!list_edges_pass(j, d, length(d)))
                        continue;
                    vec3 o = o0;
                    if (!one_origin)   // a lens point per sub-ray: made again (sub_dir keeps directions only)
                        camera_subray(p.z, pixel, vec2(size), i, o, d);
                    Ray r = primary_ray(p.z, o, d);
                    Hit h;
                    h.prim = sub_tri[base + i];
                    h.t = sub_t[base + i];
                    if (bvh_test_triangle(ray_shear(r), list_slot[j], list_tri[0][j], list_tri[1][j], list_tri[2][j],
                                          r.tmin, h)) {
                        sub_tri[base + i] = h.prim;
                        sub_t[base + i] = h.t;
                        hit = true;
                    }
                }
                if (hit && one_origin)
                    reach = pixel_reach(base, live, co, c);
            }
        }
        if (!list_next(head, b, n, load, live != 0u, reach))
            break;   // uniform: no pixel of the group needs the next load
    }
}
#endif
#endif
