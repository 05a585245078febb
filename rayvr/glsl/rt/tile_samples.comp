#version 430
// HVVR's sample testing, the third stage of tile-list primary visibility (after accel/tile_cull.comp's
// entry cut and accel/tile_tris.comp's triangle lists; frame/passes/primary_rays.py): a workgroup is a
// frame tile's pixels (SAMPLE_GROUP of them: the whole TILE_W x TILE_H tile, or a band of its rows
// where the sub-rays' state would not fit workgroup memory), an invocation one pixel with every
// sub-ray it casts. The group loads the tile's list SAMPLE_GROUP triangles at a time into workgroup
// memory, each triangle set up once for all the group's pixels and sub-rays, and every pixel tests
// its sub-rays against them. Exact: every sub-ray gets the triangle and distance per-ray traversal
// gives it, because the list holds every triangle of the tile's frustum, the filters below only
// cull, and each sub-ray's candidates go through the BVH leaves' own test (accel/bvh.glsl
// bvh_test_triangle, whose tie rule makes hits independent of the order), on the very ray
// rt/primary.comp casts.
//
// The filters, where every ray of the group leaves one origin (every camera model but thin-lens):
//   - 2D edge functions in the tile's own frame (c, u, v; c its central direction, tile_planes[4]):
//     a direction d with d.c > 0 (all of a culled tile's rays) is the point (su, sv) = (d.u, d.v) / d.c,
//     and the plane through the origin and a triangle's edge AB, normal e = A x B, gives the linear
//     edge function E(su, sv) = e.c + su e.u + sv e.v, of the sign of e.d. A sub-ray is a candidate of a
//     triangle only where all three are >= minus the rounding bound (EDGE_SLACK times the edge's
//     vertex distances, times |d| / d.c), HVVR's 2D edge test;
//   - a pixel's sub-ray points are one affine map of their footprint offsets, widened by how far any
//     lies off it (below): two multiply-adds an edge and sub-ray, no per-sub-ray registers;
//   - the pixel first: the same three functions over the box of its footprint reject the triangle
//     for all its sub-rays at once (HVVR's per-tile classification, per pixel);
//   - depth: lists are sorted by a lower bound of c.x over each triangle; a pixel stops once that
//     passes c.x of every sub-ray's points up to its closest hit (c.d <= 1 for unit d: c.o + t), the
//     group stops loading once every pixel has, and a sub-ray skips the exact test likewise.
// Rays of several origins (thin-lens) have no edge functions: every listed triangle within reach
// goes to the exact test.
//
// SAMPLE_MODE 0: sub-ray `subsample` of each pixel (1x, an SSAA round), written as rt/primary.comp's
//   PRIMARY_MODE 0 writes it; 1: all CAMERA_SUBRAYS sub-rays (the MSAA trace; with CHANNEL_SAMPLES 3,
//   those of all three colour channel sets, a block of sub-rays and an affine map a set), merged into
//   msaa_hits and msaa_count as PRIMARY_MODE 1 does (frame/passes/primary_rays.py msaa_lists is the
//   numpy twin of both merges).
// Tiles whose list overflowed (TILE_OVERFLOW) or that were not culled are left to rt/primary.comp with
// TILE_LIST_OVERFLOW 1, per ray from their entries.
#include "../layout.glsl"
#ifndef TILE_TRIS                 // the pass sets them (frame/passes/primary_rays.py)
#define TILE_TRIS DEFAULT_TILE_TRIS
#define TILE_TRIS_BINDING SSBO_TILE_TRIS
#endif
#ifndef TILE_ENTRIES_BINDING
#define TILE_RAYS DEFAULT_TILE_RAYS
#define TILE_ENTRIES DEFAULT_TILE_ENTRIES
#define TILE_ENTRIES_BINDING SSBO_TILE_ENTRIES
#define TILE_PLANES_BINDING SSBO_TILE_PLANES
#endif
#ifndef SAMPLE_MODE
#define SAMPLE_MODE 0
#endif
#ifndef SAMPLE_GROUP
#define SAMPLE_GROUP TILE_RAYS
#endif
#ifndef MSAA_SLOTS
#define MSAA_SLOTS 1
#endif
#ifndef SAMPLED
#define SAMPLED 0
#endif
layout(local_size_x = SAMPLE_GROUP) in;
#include "../accel/bvh.glsl"   // with TILE_ENTRIES_BINDING: tile_planes
#include "../accel/tile_frustum.glsl"  // beam_frame
#include "../common/camera.glsl"
#include "primary_ray.glsl"
#define MSAA_OUT (SAMPLE_MODE == 1)
#include "primary_out.glsl"
#include "same_surface.glsl"

#if SAMPLE_MODE == 1
#define PIXEL_RAYS CAMERA_SUBRAYS
#define RAY_BLOCKS CHANNEL_SAMPLES   // blocks of sub-rays: one a colour channel set, each its own map
#else
#define PIXEL_RAYS 1
#define RAY_BLOCKS 1
#endif
#define BLOCK_RAYS (PIXEL_RAYS / RAY_BLOCKS)
#define BANDS (TILE_RAYS / SAMPLE_GROUP)   // workgroups a tile
#define BAND_ROWS (TILE_H / BANDS)

layout(std430, binding = TILE_TRIS_BINDING) readonly restrict buffer TileTris { uvec2 tile_tris[]; };

shared vec4 list_edge[3][SAMPLE_GROUP];   // the load's edge functions (E at (0, 0), dE/dsu, dE/dsv, slack)
#if !MSAA_OUT
shared vec2 sub_offset[PIXEL_RAYS];       // each sub-ray's footprint offset (primary_out.glsl's with MSAA)
#endif
shared uint list_slot[SAMPLE_GROUP];
shared float list_key[SAMPLE_GROUP];
shared uint list_more[2];                 // some pixel still needs the next load (by parity)
shared uint list_leader;
shared uint list_one_origin;
shared vec3 list_origin;
// Each pixel's sub-rays' closest hits so far, sub-ray-major (sub-ray k of every pixel, then k + 1).
shared uint sub_tri[PIXEL_RAYS * SAMPLE_GROUP];
shared float sub_t[PIXEL_RAYS * SAMPLE_GROUP];
#if SAMPLE_MODE == 1
shared uint group_count;
#endif
#define SUB(k) (uint(k) * uint(SAMPLE_GROUP) + lid)
uniform int subsample;  // SAMPLE_MODE 0

#if SAMPLE_MODE == 1
// The MSAA list of pixel p from its sub-rays' hits (sub_tri, sub_t of invocation lid), as
// rt/primary.comp's msaa_merge makes it (frame/passes/primary_rays.py msaa_lists, its numpy twin):
// the entries (rt/same_surface.glsl; the background counts as one) in order of their first sub-ray, the first
// MSAA_SLOTS kept (sub-rays on the others dropped), stored most covered first (ties in order of first
// sub-ray), each with its coverage and the sub-ray nearest its coverage mask's mean footprint offset
// (the first of equally near ones), whose distance it keeps. Returns their number.
uint msaa_store_pixel(ivec3 p, ivec2 size, uint lid) {
    ivec3 extent = imageSize(img_triangle);
    uint pixels = uint(extent.x * extent.y * extent.z);
    uint index = uint((p.z * size.y + p.y) * size.x + p.x);
    if (!(camera_footprint(p.z, vec2(p.xy) + 0.5, vec2(size)) > 0.0)) {
        HIT(0) = uvec4(BVH_MISS, 0u, 0u, 0u);  // no sample at this pixel (foveated): an empty list, filled for display
        return 0u;
    }
    SubMask masks[MSAA_SLOTS];
    uint n = 0u;
    SubMask placed = MASK_NONE;  // sub-rays in an entry already (or dropped with one past MSAA_SLOTS)
    for (uint k = 0u; k < uint(PIXEL_RAYS); ++k) {
        if (!mask_empty(placed & MASK_BIT(k))) continue;
        // a new entry: every sub-ray linked to k (rt/same_surface.glsl), directly or through others
        SubMask entry = MASK_BIT(k), frontier = entry;
        while (!mask_empty(frontier)) {
            uint m = mask_lsb(frontier), tri = sub_tri[SUB(m)], surface = surface_of(tri);
            frontier = mask_drop_lsb(frontier);
            for (uint o = k + 1u; o < uint(PIXEL_RAYS); ++o) {
                uint other = sub_tri[SUB(o)];
                if (mask_empty((entry | placed) & MASK_BIT(o)) &&
                    same_surface(tri, surface, sub_t[SUB(m)], other, surface_of(other), sub_t[SUB(o)])) {
                    entry |= MASK_BIT(o);
                    frontier |= MASK_BIT(o);
                }
            }
        }
        placed |= entry;
        if (n < uint(MSAA_SLOTS)) masks[n++] = entry;
    }
    uint coverage[MSAA_SLOTS], covered = 0u;
    for (uint s = 0u; s < n; ++s) {
        coverage[s] = msaa_coverage(masks[s]);
        covered += coverage[s];
    }
    for (uint s = 0u; s < n; ++s) {
        uint pop = mask_count(masks[s]), rank = 0u;
        for (uint o = 0u; o < n; ++o) {
            uint po = mask_count(masks[o]);
            rank += uint(po > pop || (po == pop && o < s));
        }
        uint best = msaa_representative(masks[s]);
        uint meta = best | (rank == 0u ? (n << 8) | (covered << 16) : 0u);
        HIT(rank) = uvec4(sub_tri[SUB(best)], coverage[s], meta, floatBitsToUint(sub_t[SUB(best)]));
    }
    return n;
}
#endif

// The camera sub-ray index of this pixel's ray k.
uint pixel_subray(uint k) {
#if SAMPLE_MODE == 1
    return k;
#else
    return uint(subsample);
#endif
}

// c.x of a ray's points up to distance t, a bound for unit d (c.d <= 1), with rounding slack: a
// triangle whose list key (a lower bound of c.x over it) lies beyond holds no hit closer than t.
float pixel_reach(float co, float t) {
    return co + t + TILE_SLACK * (abs(co) + t);
}

void main() {
    uint lid = gl_LocalInvocationIndex;
    uint band = gl_WorkGroupID.y % uint(BANDS);
    ivec3 p = ivec3(int(gl_WorkGroupID.x) * TILE_W + int(lid % uint(TILE_W)),
                    int(gl_WorkGroupID.y / uint(BANDS)) * TILE_H + int(band) * BAND_ROWS + int(lid / uint(TILE_W)),
                    int(gl_WorkGroupID.z));
    ivec2 size = imageSize(img_triangle).xy;
    uint tile = primary_tile(p, size), head = tile * uint(TILE_TRIS + 1);
    uint n = tile_tris[head].x;
    if (n == TILE_OVERFLOW)
        return;   // the whole group: rt/primary.comp's TILE_LIST_OVERFLOW casts it
    bool inside = all(lessThan(p.xy, size));
    vec2 pixel = vec2(p.xy) + 0.5;
    vec3 c = tile_planes[5u * tile + 4u].xyz;
    vec3 u, v;
    beam_frame(c, u, v);

    // The pixel's sub-ray points (su, sv) as affine maps of their footprint offsets o (camera_subray_offset,
    // in units of the footprint's step), one a block of sub-rays (a colour channel set's): q(o) =
    // q_mid + J o, with J from the block's central ray and its rays one step right and up (the same
    // for every sub-ray of the block: no per-sub-ray registers), and `bend`, the farthest any
    // sub-ray's own point lies from its affine one (0 up to rounding for the planar models, the lens
    // curvature inside a pixel for the distorted one), which the edge tests add to their slack times
    // the edge function's gradient. Each sub-ray also gets its start here (a miss at tmax where it
    // traces; nothing at t 0 where the sample makes no ray).
    // co: the largest c.o of the pixel's origins (several with a lens), which the reaches use.
    // (pixels past the image edge of a partial tile make no ray: no footprint lookup outside the image)
    float step_size = inside ? max(camera_footprint(p.z, pixel, vec2(size)), 1.0) : 1.0;
    vec2 q_mid[RAY_BLOCKS];
    mat2 J[RAY_BLOCKS];
    float bend[RAY_BLOCKS];
    for (int b = 0; b < RAY_BLOCKS; ++b) {
#if RAY_BLOCKS > 1
        camera_channel_override = camera_subray_channel(uint(b * BLOCK_RAYS));
#endif
        vec3 o0, dm, dx, dy;
        camera_ray_at(p.z, pixel, vec2(size), vec2(0.0), o0, dm);
        camera_ray_at(p.z, pixel + vec2(step_size, 0.0), vec2(size), vec2(0.0), o0, dx);
        camera_ray_at(p.z, pixel + vec2(0.0, step_size), vec2(size), vec2(0.0), o0, dy);
        camera_channel_override = -1;
        q_mid[b] = vec2(dot(dm, u), dot(dm, v)) / dot(dm, c);
        J[b] = mat2(vec2(dot(dx, u), dot(dx, v)) / dot(dx, c) - q_mid[b], vec2(dot(dy, u), dot(dy, v)) / dot(dy, c) - q_mid[b]);
        bend[b] = 0.0;
    }
    for (uint k = lid; k < uint(PIXEL_RAYS); k += uint(SAMPLE_GROUP))   // (a band of 32 pixels at 48 sub-rays)
        sub_offset[k] = camera_subray_offset(pixel_subray(k));
    barrier();
    SubMask traced = MASK_NONE;   // bit k: sub-ray k traces
    vec3 origin = vec3(0.0);
    bool one_origin = true;   // every sub-ray of the pixel from `origin`
    float co = -3.0e38, t_far = 0.0, q_far = 0.0;
    for (int k = 0; k < PIXEL_RAYS; ++k) {
        vec3 o, d;
        bool valid = inside && camera_subray(p.z, pixel, vec2(size), pixel_subray(uint(k)), o, d);
        Ray r = primary_ray(p.z, o, d);
        sub_tri[SUB(k)] = BVH_MISS;
        sub_t[SUB(k)] = valid ? r.tmax : 0.0;
        if (valid && bvh_ray_valid(r)) {
            int b = k / BLOCK_RAYS;
            vec2 q = vec2(dot(d, u), dot(d, v)) / dot(d, c);
            bend[b] = max(bend[b], length(q - (q_mid[b] + J[b] * sub_offset[k])));
            q_far = max(q_far, dot(q, q));
            one_origin = one_origin && (mask_empty(traced) || all(equal(o, origin)));
            traced |= MASK_BIT(uint(k));
            origin = o;
            co = max(co, dot(c, o));
            t_far = max(t_far, r.tmax);
        }
    }
    for (int b = 0; b < RAY_BLOCKS; ++b)
        bend[b] = bend[b] * 1.001 + 1e-30;   // (its own rounding)
    bool live = !mask_empty(traced);
    float reach = pixel_reach(co, t_far);
    // |d| / d.c for every sub-ray of the pixel, at most: the edge slack's scale in the tile's frame
    float stretch = sqrt(1.0 + q_far) * 1.001;
    // the box of the offsets: the footprint's [-1/2, 1/2]^2 (camera_subpixel)
    vec2 o_half = vec2(0.5);

    // One origin for the whole group? (the edge functions' condition)
    if (lid == 0u) {
        list_leader = 0xFFFFFFFFu;
        list_one_origin = 1u;
        list_origin = vec3(0.0);   // read by every invocation even when no pixel of the group is live
#if SAMPLE_MODE == 1
        group_count = 0u;
#endif
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
    bool edges = list_one_origin != 0u;
    vec3 group_origin = list_origin;

    uint load = 0u;
    for (uint base = 0u; base < n; base += uint(SAMPLE_GROUP), ++load) {
        uint j = base + lid;
        if (j < n) {
            uvec2 e = tile_tris[head + 1u + j];
            vec3 A = bvh_tris[3u * e.x].xyz - group_origin, B = bvh_tris[3u * e.x + 1u].xyz - group_origin,
                 C = bvh_tris[3u * e.x + 2u].xyz - group_origin;
            list_slot[lid] = e.x;
            list_key[lid] = uintBitsToFloat(e.y);
            // Edge planes with their slack. Zero functions (several origins; a triangle nearly edge-on
            // to the origin, whose triple product's sign is not sure) pass every ray.
            vec3 ab = cross(A, B), bc = cross(B, C), ca = cross(C, A);
            float triple = dot(ab, C), la = length(A), lb = length(B), lc = length(C);
            float sg = edges && abs(triple) > EDGE_SLACK * la * lb * lc ? sign(triple) : 0.0;
            list_edge[0][lid] = vec4(sg * vec3(dot(ab, c), dot(ab, u), dot(ab, v)), abs(sg) * EDGE_SLACK * la * lb);
            list_edge[1][lid] = vec4(sg * vec3(dot(bc, c), dot(bc, u), dot(bc, v)), abs(sg) * EDGE_SLACK * lb * lc);
            list_edge[2][lid] = vec4(sg * vec3(dot(ca, c), dot(ca, u), dot(ca, v)), abs(sg) * EDGE_SLACK * lc * la);
        }
        if (lid == 0u)
            list_more[load & 1u] = 0u;
        barrier();
        uint m = min(uint(SAMPLE_GROUP), n - base);
        if (live) {
            for (uint i = 0u; i < m; ++i) {
                float key = list_key[i];
                if (key > reach)
                    break;   // sorted: every later triangle lies beyond too
                // Each edge function as one of a block's footprint offset o: a + g.o (g = J^T grad E),
                // with its slack: the rounding bound, and the gradient times the bend.
                vec4 e0 = list_edge[0][i], e1 = list_edge[1][i], e2 = list_edge[2][i];
                vec3 a[RAY_BLOCKS];
                vec2 g0[RAY_BLOCKS], g1[RAY_BLOCKS], g2[RAY_BLOCKS];
                float best = -1.0;
                for (int b = 0; b < RAY_BLOCKS; ++b) {
                    a[b] = vec3(e0.x + dot(e0.yz, q_mid[b]) + e0.w * stretch + (abs(e0.y) + abs(e0.z)) * bend[b],
                                e1.x + dot(e1.yz, q_mid[b]) + e1.w * stretch + (abs(e1.y) + abs(e1.z)) * bend[b],
                                e2.x + dot(e2.yz, q_mid[b]) + e2.w * stretch + (abs(e2.y) + abs(e2.z)) * bend[b]);
                    g0[b] = e0.yz * J[b];
                    g1[b] = e1.yz * J[b];
                    g2[b] = e2.yz * J[b];
                    // the pixel: the largest value of each edge function over the box of its offsets
                    float block_best = min(min(a[b].x + dot(abs(g0[b]), o_half), a[b].y + dot(abs(g1[b]), o_half)),
                                           a[b].z + dot(abs(g2[b]), o_half));
                    best = max(best, block_best < 0.0 ? -1.0 : 1.0);   // (a NaN passes: the exact test decides)
                }
                if (best < 0.0)
                    continue;
                SubMask candidates = MASK_NONE;   // (the sub-rays that trace, below)
                for (int k = 0; k < PIXEL_RAYS; ++k) {
                    int b = k / BLOCK_RAYS;
                    vec2 ok = sub_offset[k];
                    float inside_e = min(min(a[b].x + dot(g0[b], ok), a[b].y + dot(g1[b], ok)), a[b].z + dot(g2[b], ok));
                    if (!(inside_e < 0.0)) candidates |= MASK_BIT(uint(k));
                }
                uint slot = list_slot[i];
                for (candidates &= traced; !mask_empty(candidates); candidates = mask_drop_lsb(candidates)) {
                    uint k = mask_lsb(candidates);
                    Hit h;
                    h.t = sub_t[SUB(k)];
                    h.prim = sub_tri[SUB(k)];
                    if (key > pixel_reach(co, h.t))
                        continue;
                    vec3 o, d;
                    camera_subray(p.z, pixel, vec2(size), pixel_subray(k), o, d);
                    Ray r = primary_ray(p.z, o, d);
                    if (bvh_test_triangle(ray_shear(r), slot, bvh_tris[3u * slot], bvh_tris[3u * slot + 1u],
                                          bvh_tris[3u * slot + 2u], r.tmin, h)) {
                        sub_t[SUB(k)] = h.t;
                        sub_tri[SUB(k)] = h.prim;
                    }
                }
            }
            // the pixel's reach after this load: its sub-rays' closest hits so far
            t_far = 0.0;
            for (int k = 0; k < PIXEL_RAYS; ++k)
                t_far = max(t_far, mask_empty(traced & MASK_BIT(uint(k))) ? 0.0 : sub_t[SUB(k)]);
            reach = pixel_reach(co, t_far);
            if (base + uint(SAMPLE_GROUP) < n && !(uintBitsToFloat(tile_tris[head + 1u + base + uint(SAMPLE_GROUP)].y) > reach))
                list_more[load & 1u] = 1u;
        }
        barrier();
        if (list_more[load & 1u] == 0u)
            break;   // uniform: no pixel of the group needs the next load
    }

#if SAMPLE_MODE == 0
    if (!inside)
        return;
    store_cast(p, camera_footprint(p.z, pixel, vec2(size)) > 0.0, sub_tri[SUB(0)], sub_t[SUB(0)], uint(subsample));
#else
    uint count = 0u;
    if (inside)
        count = msaa_store_pixel(p, size, lid);
    if (count > 1u)
        atomicMax(group_count, count);
    barrier();
    // one global atomic a workgroup at most, and only for a count above 1 (rt/primary.comp does the same)
    if (lid == 0u && group_count > 1u && group_count > msaa_count)
        atomicMax(msaa_count, group_count);
#endif
}
