#version 430
// G-buffer resolve: from each pixel's triangle ID (visibility raster or ray-traced primary
// hits) and the pixel's own camera ray, compute the exact hit on that triangle and fill every
// G-buffer channel (rayvr/gl/gpu_layout.py CHANNELS). Positions lie on the pixel's ray by
// construction, so ray-traced passes and the G-buffer register exactly; texture LOD comes
// from ray differentials (the neighbouring pixels' rays on the same triangle plane).
// Normal, material and base colour come from common/triangle_surface.glsl, which secondary-ray
// hits (rt/hit_surface.glsl) share.
// PRIMARY_RAYS 1: the triangle IDs come from rt/primary.comp, which leaves the hit distance in
// position.w instead of a depth buffer, and in position.x the camera sub-ray it hit with (uint
// bits; cameras/sampling.glsl): the resolve casts the same sub-ray.
#ifndef PRIMARY_RAYS
#define PRIMARY_RAYS 0
#endif
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/triangle_surface.glsl"
#include "../common/camera.glsl"
#include "../common/round_skip.glsl"

layout(binding = GB_UNIT_DEPTH) uniform sampler2DArray gb_depth;
#if PRIMARY_RAYS
layout(rgba32f, binding = GB_IMAGE_POSITION) uniform image2DArray img_position;
#else
layout(rgba32f, binding = GB_IMAGE_POSITION) uniform writeonly image2DArray img_position;
#endif
layout(rgba16f, binding = GB_IMAGE_NORMAL) uniform writeonly image2DArray img_normal;
layout(rgba16f, binding = GB_IMAGE_ALBEDO) uniform writeonly image2DArray img_albedo;
layout(rgba16f, binding = GB_IMAGE_EMISSION) uniform writeonly image2DArray img_emission;
layout(rg32ui, binding = GB_IMAGE_MATERIAL) uniform writeonly uimage2DArray img_material;
layout(r32ui, binding = GB_IMAGE_TRIANGLE) uniform uimage2DArray img_triangle;
layout(r32f, binding = GB_IMAGE_LINEAR_DEPTH) uniform writeonly image2DArray img_linear_depth;

// Barycentrics (b1, b2) of the point where ray (o, d) meets the plane of (v0, e1, e2).
vec2 plane_barycentrics(vec3 o, vec3 d, vec3 v0, vec3 e1, vec3 e2, vec3 ng, out float t) {
    t = dot(v0 - o, ng) / dot(d, ng);
    vec3 q = o + t * d - v0;
    float inv = 1.0 / dot(ng, ng);
    return vec2(dot(cross(q, e2), ng), dot(cross(e1, q), ng)) * inv;
}

void main() {
    ivec3 p = round_pixel();  // (an MSAA round: over its listed tiles)
    vec2 size = vec2(imageSize(img_position).xy);
    if (any(greaterThanEqual(p.xy, ivec2(size)))) return;
    if (round_skips(p)) return;  // an MSAA round's pixel with nothing new: its G-buffer stays
    uint tri = imageLoad(img_triangle, p).x;
#if PRIMARY_RAYS
    vec4 primary = imageLoad(img_position, p);
    float ray_t = primary.w;
    uint sub = floatBitsToUint(primary.x);
    if (tri == NO_HIT) {
#else
    float z = texelFetch(gb_depth, p, 0).x;
    if (z <= 0.0 || tri == NO_HIT) {  // reversed-Z: 0 is the cleared (infinitely far) value
#endif
        imageStore(img_position, p, vec4(0.0));
        imageStore(img_normal, p, vec4(0.0));
        imageStore(img_albedo, p, vec4(0.0));
        imageStore(img_emission, p, vec4(0.0));
        imageStore(img_material, p, uvec4(NO_HIT, BACKGROUND_EFFECT, 0u, 0u));
        imageStore(img_triangle, p, uvec4(NO_HIT));
        imageStore(img_linear_depth, p, vec4(0.0));
        return;
    }
    int eye = p.z;
    vec3 o, d;
#if PRIMARY_RAYS
    camera_subray(eye, vec2(p.xy) + 0.5, size, sub, o, d);
#else
    camera_ray(eye, vec2(p.xy) + 0.5, size, o, d);
#endif
    TriangleVerts tv = scene_triangle(tri);
    vec3 e1 = tv.p[1] - tv.p[0], e2 = tv.p[2] - tv.p[0];
    vec3 ng = cross(e1, e2);
    float t;
    vec2 b = plane_barycentrics(o, d, tv.p[0], e1, e2, ng, t);
    float view_dist_along = camera_depth_per_distance(eye, d);
    if (!(abs(dot(d, ng)) > 1e-7 * length(ng)) || !(t > 0.0)) {
        // Seen edge-on: the plane hit is ill-conditioned; take the distance from the depth buffer.
#if PRIMARY_RAYS
        t = ray_t;
#else
        t = eye_view_depth(z) / view_dist_along;
#endif
        vec3 q = o + t * d - tv.p[0];
        b = vec2(dot(cross(q, e2), ng), dot(cross(e1, q), ng)) / max(dot(ng, ng), 1e-30);
    }
    // Pixel centres the rasterizer counted as inside may fall a rounding error outside.
    vec3 w = max(vec3(1.0 - b.x - b.y, b), 0.0);
    w /= w.x + w.y + w.z;
    vec3 position = o + t * d;

    uint mi = triangle_material[tri];
    float lod = 0.0;
    if (materials[mi].texture_layer >= 0) {
        float tx, ty;
        vec3 d_x, d_y;
#if PRIMARY_RAYS
        camera_subray_neighbours(eye, vec2(p.xy) + 0.5, size, sub, d_x, d_y);
#else
        camera_ray_neighbours(eye, vec2(p.xy) + 0.5, size, d_x, d_y);
#endif
        vec2 bx = plane_barycentrics(o, d_x, tv.p[0], e1, e2, ng, tx);
        vec2 by = plane_barycentrics(o, d_y, tv.p[0], e1, e2, ng, ty);
        vec2 duv1 = tv.uv[1] - tv.uv[0], duv2 = tv.uv[2] - tv.uv[0];
        vec2 ddx = (bx.x - b.x) * duv1 + (bx.y - b.y) * duv2;
        vec2 ddy = (by.x - b.x) * duv1 + (by.y - b.y) * duv2;
        // The LOD is computed here and used with textureLod, per pixel: implementations may share
        // one textureGrad LOD across a SIMD group, where one grazing pixel would blur its
        // neighbours. A neighbour ray that misses the plane (grazing) takes the other axis' size.
        vec2 tex_size = vec2(textureSize(base_color_textures, 0).xy);
        float fx = tx > 0.0 ? length(ddx * tex_size) : 0.0;
        float fy = ty > 0.0 ? length(ddy * tex_size) : 0.0;
        float footprint = max(max(fx, fy), 1e-6);
        lod = clamp(log2(footprint), 0.0, log2(max(tex_size.x, tex_size.y)));
    }
    Surface s = triangle_surface(tri, tv, w, ng, d, lod);
    imageStore(img_position, p, vec4(position, t * view_dist_along));
    imageStore(img_linear_depth, p, vec4(t * view_dist_along));
    imageStore(img_normal, p, vec4(s.normal, s.roughness));
    imageStore(img_albedo, p, vec4(s.base_color, s.metallic));
    imageStore(img_emission, p, vec4(s.emission, 1.0));
    imageStore(img_material, p, uvec4(s.material, s.effect, 0u, 0u));
}
