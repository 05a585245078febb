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
#ifndef RAYVR_RT_TILE_LIST_CAST_GLSL
#define RAYVR_RT_TILE_LIST_CAST_GLSL


shared vec4 list_tri[3][PRIMARY_GROUP];    // the load's vertices (a.w: the original ID bits)
shared vec4 list_edge[3][PRIMARY_GROUP];   // edge planes through the group's origin, w: their slack
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

void cast_tile_list(Ray r, uint tile, bool valid, inout Hit h) {
    uint lid = gl_LocalInvocationIndex, head = tile * uint(TILE_TRIS + 1);
    RayShear s;
    vec3 inv;
    Hit hit;
    bool live = valid && bvh_begin(r, hit, s, inv);
    if (valid)
        h = hit;   // a valid ray that traces nothing is a miss at tmax, as trace_closest makes it
    uint n = tile_tris[head].x;   // not TILE_OVERFLOW: those tiles are rt/primary.comp's TILE_LIST_PART 2
    // One origin for the whole group? (the edge filter's condition)
    if (lid == 0u) {
        list_leader = 0xFFFFFFFFu;
        list_one_origin = 1u;
    }
    barrier();
    if (live)
        atomicMin(list_leader, lid);
    barrier();
    if (lid == list_leader)
        list_origin = r.origin;
    barrier();
    if (live && any(notEqual(r.origin, list_origin)))
        list_one_origin = 0u;
    barrier();
    bool edges = list_one_origin != 0u;
    vec3 origin = list_origin;
    vec3 c = tile_planes[5u * tile + 4u].xyz;
    float co = dot(c, r.origin), cd = dot(c, r.direction), dlen = length(r.direction);
    uint load = 0u;
    for (uint base = 0u; base < n; base += uint(PRIMARY_GROUP), ++load) {
        uint k = base + lid;
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
        }
        if (lid == 0u)
            list_more[load & 1u] = 0u;
        barrier();
        uint m = min(uint(PRIMARY_GROUP), n - base);
        if (live) {
            float reach = list_reach(co, cd, h.t);
            for (uint j = 0u; j < m; ++j) {
                if (list_key[j] > reach)
                    break;   // sorted: every later triangle lies beyond too
                // one branch for the three planes (no short-circuit: their loads overlap)
                vec4 e0 = list_edge[0][j], e1 = list_edge[1][j], e2 = list_edge[2][j];
                float inside = min(min(dot(e0.xyz, r.direction) + e0.w * dlen, dot(e1.xyz, r.direction) + e1.w * dlen),
                                   dot(e2.xyz, r.direction) + e2.w * dlen);
                if (!(inside < 0.0) &&   // (a NaN passes: the exact test decides)
                    bvh_test_triangle(s, list_slot[j], list_tri[0][j], list_tri[1][j], list_tri[2][j], r.tmin, h))
                    reach = list_reach(co, cd, h.t);
            }
            if (base + uint(PRIMARY_GROUP) < n && !(uintBitsToFloat(tile_tris[head + 1u + base + uint(PRIMARY_GROUP)].y) > reach))
                list_more[load & 1u] = 1u;
        }
        barrier();
        if (list_more[load & 1u] == 0u)
            break;   // uniform: no ray of the group needs the next load
    }
}
#endif
