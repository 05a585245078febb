#version 430
// Tile frusta of a planar camera model (the pinhole's; frame/passes/primary_rays.py runs this kernel
// in place of accel/tile_cull.comp's TILE_STAGE 1 when a block-culled frame's camera is rasterizable):
// one invocation a frame tile instead of a workgroup of its pixels, with no reductions.
// A planar model's sub-ray directions are an affine map of their image positions, all from one
// origin, so over a tile's sample positions every extreme tile_cull.comp reduces over the tile's
// rays lies at a vertex of their convex hull: the slopes su = d.u / d.c and sv (linear-fractional in
// the position), the far point's c.x (it lies on the far plane: affine), the reach tmax |d| (the
// distance to that point: convex) and the least cosine to c (affine over convex). Every pixel has
// the same sub-sample pattern, so that hull's vertices are among the sub-samples of the tile's four
// corner pixels: their 4 x CAMERA_SUBSAMPLES rays give the planes of all its rays, rounding aside,
// which the slack covers (c: their unit directions' normalized mean). Writes what stage 1 writes:
// tile_planes (5 a tile) and tile_boxes (3 a tile); tests/test_tile_culling_frame.py checks every
// sub-ray against the planes, and that each side plane touches one.
// A tile with a corner ray the camera does not make is not culled (its cut is the root's children).
#include "../layout.glsl"
#ifndef TILE_PLANES_BINDING   // the pass sets them (frame/passes/primary_rays.py)
#define TILE_PLANES_BINDING SSBO_TILE_PLANES
#define TILE_BOXES_BINDING SSBO_TILE_BOXES
#endif
layout(local_size_x = PLANAR_BEAM_GROUP) in;   // tiles a workgroup (layout.glsl)

#define TILE_CULL_WRITER 1   // declares tile_planes writable itself
#include "bvh.glsl"   // bvh_ray_valid
#include "tile_frustum.glsl"
#include "../common/camera.glsl"
#include "../rt/primary_ray.glsl"

layout(std430, binding = TILE_PLANES_BINDING) writeonly restrict buffer Planes { vec4 tile_planes[]; };
layout(std430, binding = TILE_BOXES_BINDING) writeonly restrict buffer Boxes { vec4 tile_boxes[]; };
uniform ivec2 image_size;   // per eye

void main() {
    ivec2 tiles = (image_size + ivec2(TILE_W, TILE_H) - 1) / ivec2(TILE_W, TILE_H);
    int i = int(gl_GlobalInvocationID.x), eye = int(gl_WorkGroupID.z);
    if (i >= tiles.x * tiles.y)
        return;
    uint tile = uint(eye * tiles.x * tiles.y + i);
    ivec2 p0 = ivec2(i % tiles.x, i / tiles.x) * ivec2(TILE_W, TILE_H);
    ivec2 p1 = min(p0 + ivec2(TILE_W, TILE_H), image_size) - 1;   // the tile's last pixel inside the image
    // (two passes over the corner sub-rays: their mean direction c, then their extremes about it)
    vec3 mean = vec3(0.0), origin = vec3(0.0);
    bool valid = true;
    vec4 mins = vec4(3.0e38), maxs = vec4(-3.0e38);
    vec3 c = vec3(0.0, 0.0, 1.0), u, v;
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 1) {
            c = length(mean) > 0.0 ? normalize(mean) : c;
            beam_frame(c, u, v);
        }
        for (int k = 0; k < 4 * CAMERA_SUBSAMPLES; ++k) {
            bvec2 high = bvec2((k & 1) != 0, (k & 2) != 0);
            vec2 pixel = mix(vec2(p0), vec2(p1), high) + 0.5;   // (GLSL 4.30 mixes floats only)
            float f = camera_footprint(eye, pixel, vec2(image_size));
            vec3 o, d;
            bool made = camera_ray_at(eye, pixel + camera_subpixel(uint(k / 4)) * max(f, 1.0), vec2(image_size),
                                      vec2(0.0), o, d) && f > 0.0;
            Ray r = primary_ray(eye, o, d);
            valid = valid && made && bvh_ray_valid(r);
            origin = o;
            if (pass == 0) {
                mean += normalize(d);
                continue;
            }
            beam_add_ray(c, u, v, o, d, r.tmax, mins, maxs);   // as tile_cull.comp's pass over its rays
        }
    }
    vec4 slopes = widened_slopes(vec4(mins.y, -mins.z, mins.w, maxs.x));
    vec3 n[4];
    beam_side_normals(c, u, v, slopes, n);
    vec4 planes[5];
    beam_planes(c, n, box_offsets(n, origin, origin), maxs, planes);
    bool fallback = !valid || !(mins.x > TILE_MIN_COS);   // also NaN
    for (int k = 0; k < 5; ++k)
        tile_planes[5u * tile + uint(k)] = fallback ? vec4(0.0, 0.0, 0.0, 1.0) : planes[k];
    tile_boxes[3u * tile] = vec4(origin, maxs.w);
    tile_boxes[3u * tile + 1u] = vec4(origin, 0.0);
    tile_boxes[3u * tile + 2u] = slopes;
}
