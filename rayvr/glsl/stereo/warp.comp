#version 430
// Stereo `warp` (Widmer et al. 2015 §5.1; rayvr/frame/passes/warp.py): one eye synthesized from the
// central view. Each eye pixel's camera ray is traced through the central view's quadtree
// (ssrt/quadtree.glsl qt_trace_layers, each surface a slab `warp_thickness` deep in relative z);
// camera slot 0 is the central view (tree layer 0, and 1 for its second depth layer), slot 1 the
// eye being made.
//   hit on the first layer        the central image's colour there; depth (and the point a
//                                 second-layer hit is shaded at) where the ray crosses the hit
//                                 pixel's triangle (triangle_crossing)
//   hit on the second layer       (WARP_LAYERS 2: surfaces behind the central view's first) that
//                                 triangle's surface at the ray's crossing, shaded like the `raster`
//                                 rung (direct light, ambient; no shadows) and tonemapped
//   passed behind every layer     (QT_OCCLUDED: a disocclusion) -> hole, inpainted from the pixel
//                                 the ray crossed just before (the background side: Widmer's
//                                 dilated occlusion volume)
//   left the central image first  (at the image borders) -> hole, the border pixel's colour
//   reached infinity on screen    the background there
// Writes colour (alpha 0 on holes) and linear view depth into layer `warp_layer`, and counts per
// eye (glsl order = frame/passes/warp.py COUNTS).
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#ifndef WARP_LAYERS
#define WARP_LAYERS 2  // frame/passes/warp.py sets it; the default lets the shader compile on its own
#endif
#include "../ssrt/quadtree.glsl"
#include "../common/gbuffer.glsl"
#include "../common/scene.glsl"
#if WARP_LAYERS > 1
#include "../common/triangle_surface.glsl"
#include "../common/lighting.glsl"
layout(binding = UNIT_LAYER2_TRIANGLE) uniform usampler2DArray layer2_triangle;
uniform vec3 ambient;
uniform float exposure;
uniform int tonemapper;
#endif

layout(rgba8, binding = IMAGE_LDR) uniform readonly image2DArray center_ldr;
layout(rgba8, binding = IMAGE_WARP_COLOR) uniform writeonly image2DArray warp_color;
layout(r32f, binding = IMAGE_WARP_DEPTH) uniform writeonly image2DArray warp_depth;
layout(std430, binding = SSBO_WARP_COUNTS) restrict buffer WarpCounts { uint warp_counts[]; };
uniform int warp_layer;
uniform float warp_thickness;

// Per eye: the pixels of each kind WARP_COUNT_<kind> (the index of the kind in rayvr/frame/passes/warp.py
// COUNTS), then the nodes tested; WARP_COUNTS words in all (layout.glsl).
shared uint group_counts[WARP_COUNTS];

// Linear view depth in the eye (slot 1) of the scene-local point `p`.
float eye_depth_of(vec3 p) { return -(transpose(eye_rotation[1]) * (p - eye_position[1])).z; }

// The point on the ray o + t d whose view depth in the central view (slot 0) is n / z (S's z).
vec3 ray_point_at(vec3 o, vec3 d, float z) {
    mat3 to_view = transpose(eye_rotation[0]);
    float da = -(to_view * (o - eye_position[0])).z, dd = -(to_view * d).z;
    return o + (dd != 0.0 ? (eye_depth.x / z - da) / dd : 0.0) * d;
}

// Where the eye's ray o + t d crosses triangle `tri`'s plane (x) and its view depth there, if that
// is within `warp_thickness` of `z` (the hit's point in S: near / central depth) and not edge-on;
// else false. The trace finds the hit in S, where z has an absolute precision of ~1e-7 from 1 at
// the near plane down (a relative error up to ~1e-7 near / depth, 5e-4 on the GPU at the room's
// far wall); the triangle's plane gives the depth the G-buffer resolve computes
// (gbuffer/resolve.comp: t along the ray times its depth per distance), so at IPD 0, where the
// eye's rays are the central view's, each eye's depth is the central view's.
bool triangle_crossing(uint tri, vec3 o, vec3 d, float z, out vec3 x, out float depth) {
    x = o; depth = 0.0;
    if (tri == NO_HIT)
        return false;
    TriangleVerts tv = scene_triangle(tri);
    vec3 ng = triangle_normal(tv);
    float dn = dot(d, ng);
    if (!(abs(dn) > 1e-7 * length(ng) * length(d)))
        return false;
    float t = dot(tv.p[0] - o, ng) / dn;
    x = o + t * d;
    float central = -(transpose(eye_rotation[0]) * (x - eye_position[0])).z;  // the crossing's central depth
    depth = t * camera_depth_per_distance(1, d);
    return t > 0.0 && abs(central * z - eye_depth.x) <= warp_thickness * eye_depth.x;
}

#if WARP_LAYERS > 1
// The second layer's triangle at central pixel `c`, at point `x` on it, seen along `d`: shaded as
// the `raster` rung shades (shade/direct.comp) and tonemapped as tonemap.comp does.
vec3 shade_second_layer(uint tri, vec3 x, vec3 d) {
    if (tri == NO_HIT) return vec3(0.0);
    TriangleVerts tv = scene_triangle(tri);
    vec3 e1 = tv.p[1] - tv.p[0], e2 = tv.p[2] - tv.p[0], ng = triangle_normal(tv), q = x - tv.p[0];
    vec2 b = vec2(dot(cross(q, e2), ng), dot(cross(e1, q), ng)) / max(dot(ng, ng), 1e-30);
    vec3 w = max(vec3(1.0 - b.x - b.y, b), 0.0);
    Surface s = triangle_surface(tri, tv, w / max(w.x + w.y + w.z, 1e-30), ng, d, 0.0);
    vec3 color = s.emission + direct_light(x, s.normal, -normalize(d), s.base_color, s.metallic, s.roughness)
               + ambient * s.base_color;
    return linear_to_srgb(tonemap(color * exposure, tonemapper));
}
#endif

void main() {
    uint li = gl_LocalInvocationIndex;
    if (li < uint(WARP_COUNTS)) group_counts[li] = 0u;
    barrier();
    ivec2 size = qt_level[0].xy;
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(p, size))) {
        vec3 o, d;
        camera_ray(1, vec2(p) + 0.5, vec2(size), o, d);
        QtResult h = qt_trace_layers(0, o, d, WARP_LAYERS, warp_thickness);
        ivec2 src = clamp(ivec2(floor(h.point.xy)), ivec2(0), size - 1);
        uint kind = WARP_COUNT_BACKGROUND;
        if (h.status == QT_HIT) {
            kind = h.layer == 0 ? WARP_COUNT_HITS : WARP_COUNT_HITS_SECOND_LAYER;
            src = h.pixel;
        } else if (h.status == QT_OCCLUDED) {
            kind = WARP_COUNT_DISOCCLUDED;
            if (h.pixel.x >= 0) src = h.pixel;
        } else if (h.status == QT_OFFSCREEN || h.status == QT_NEAR) {
            kind = WARP_COUNT_OFFSCREEN;
        }
        vec4 color = imageLoad(center_ldr, ivec3(src, 0));
        float depth = 0.0;
        if (kind == WARP_COUNT_HITS || kind == WARP_COUNT_HITS_SECOND_LAYER) {
            uint tri = texelFetch(gb_triangle, ivec3(src, 0), 0).x;
#if WARP_LAYERS > 1
            if (kind == WARP_COUNT_HITS_SECOND_LAYER) tri = texelFetch(layer2_triangle, ivec3(src, 0), 0).x;
#endif
            vec3 x;
            if (!triangle_crossing(tri, o, d, h.point.z, x, depth)) {
                x = ray_point_at(o, d, h.point.z);  // the crossing on the eye's ray, from S
                depth = eye_depth_of(x);
            }
#if WARP_LAYERS > 1
            if (kind == WARP_COUNT_HITS_SECOND_LAYER) color.rgb = shade_second_layer(tri, x, d);
#endif
        } else if (kind != WARP_COUNT_BACKGROUND) {
            vec4 fill = texelFetch(gb_position, ivec3(src, 0), 0);  // the inpainted pixel's surface
            depth = fill.w > 0.0 ? eye_depth_of(fill.xyz) : 0.0;
        }
        imageStore(warp_color, ivec3(p, warp_layer), vec4(color.rgb, kind <= WARP_COUNT_OFFSCREEN ? 0.0 : 1.0));
        imageStore(warp_depth, ivec3(p, warp_layer), vec4(max(depth, 0.0)));
        atomicAdd(group_counts[kind], 1u);
        atomicAdd(group_counts[WARP_COUNTS - 1], h.nodes);
    }
    barrier();
    if (li < uint(WARP_COUNTS) && group_counts[li] > 0u)
        atomicAdd(warp_counts[warp_layer * WARP_COUNTS + int(li)], group_counts[li]);
}
