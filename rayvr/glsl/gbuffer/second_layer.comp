#version 430
// The second depth layer (frame/passes/second_layer.py): per pixel, the nearest surface behind the
// G-buffer's along the pixel's camera ray. SECOND_LAYER_PEEL 0: the ray continued through the BVH
// past the first hit; 1: the triangle the peel raster (gbuffer/peel.frag) left. Either way the
// layer is the ray's exact crossing of that triangle's plane: layer2 = (the triangle's unit
// geometric normal facing the eye, view depth), layer2_triangle = its ID; (0, NO_HIT) where there
// is none. The normal is for the quadtree's leaf plane (ssrt/quadtree_build.comp), its only
// reader: the triangle's own plane, as for the first layer (shading reads the triangle ID).
#ifndef SECOND_LAYER_PEEL
#define SECOND_LAYER_PEEL 0
#endif
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/camera.glsl"
#include "../common/gbuffer.glsl"
#include "../common/scene.glsl"
#if SECOND_LAYER_PEEL
layout(binding = UNIT_PEEL_TRIANGLE) uniform usampler2DArray peel_triangle;
#else
#include "../accel/bvh.glsl"
#define SECOND_LAYER_SKIPS 8  // hits on the first layer's triangle (or not behind it) skipped at most
#endif
layout(rgba32f, binding = IMAGE_LAYER2) uniform writeonly image2DArray img_layer2;
layout(r32ui, binding = IMAGE_LAYER2_TRIANGLE) uniform writeonly uimage2DArray img_layer2_triangle;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 size = textureSize(gb_position, 0).xy;
    if (any(greaterThanEqual(p.xy, size))) return;
    uint first = texelFetch(gb_triangle, p, 0).x;
    float depth1 = texelFetch(gb_position, p, 0).w;
    uint tri = NO_HIT;
    vec3 o, d;
    bool ray = camera_ray(p.z, vec2(p.xy) + 0.5, vec2(size), o, d);
    float along = dot(d, eye_forward(p.z));  // view depth per unit of t
    if (first != NO_HIT && ray) {
#if SECOND_LAYER_PEEL
        tri = texelFetch(peel_triangle, p, 0).x;
#else
        float t1 = depth1 / along;
        Ray r = Ray(o, t1 * (1.0 - 1e-5), d, 3.0e38);
        for (int i = 0; i < SECOND_LAYER_SKIPS; ++i) {
            Hit h;
            if (!trace_closest(r, h)) break;
            if (h.prim != first && h.t > t1) {
                tri = h.prim;
                break;
            }
            r.tmin = max(h.t, t1) * (1.0 + 1e-7) + 1e-30;  // past the first layer's own triangle
        }
#endif
    }
    vec4 layer = vec4(0.0);
    if (tri != NO_HIT) {
        TriangleVerts tv = scene_triangle(tri);
        vec3 ng = triangle_normal(tv);
        float den = dot(d, ng);
        float t = dot(tv.p[0] - o, ng) / den;
        if (abs(den) > 1e-7 * length(ng) * length(d) && t * along > depth1) {
            layer = vec4(normalize(den > 0.0 ? -ng : ng), t * along);  // facing the eye
        } else {
            tri = NO_HIT;  // seen edge-on: no plane to trace
        }
    }
    imageStore(img_layer2, p, layer);
    imageStore(img_layer2_triangle, p, uvec4(tri));
}
