#version 430
// Stereo `warp` (Widmer et al. 2015 §5.1; rayvr/passes/warp.py): one eye synthesized from the
// central view. Each eye pixel's camera ray is traced through the central view's quadtree
// (ssrt/quadtree.glsl qt_trace, single layer: a height field); the colour is the central image's
// at the hit. Camera slot 0 is the central view (the tree's layer 0), slot 1 the eye being made.
//   hit in front of the surface there (within warp_thickness x its z): the central pixel's colour
//   hit behind it (the ray passed behind a foreground object: a disocclusion) -> hole, inpainted
//     from the background side: the pixel just before the hit along the ray (the one the ray was
//     still in front of), as Widmer's dilated occlusion volume lands on background data
//   left the central image before hitting (at the image borders) -> hole, the border pixel's colour
//   reached infinity on screen -> the background there
// Writes colour (alpha 0 on holes) and linear view depth into layer `warp_layer` of the outputs,
// and counts per eye: holes by disocclusion, holes off screen, hits, nodes tested.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "../ssrt/quadtree.glsl"
#include "../common/gbuffer.glsl"

layout(rgba8, binding = IMAGE_LDR) uniform readonly image2DArray center_ldr;
layout(rgba8, binding = IMAGE_WARP_COLOR) uniform writeonly image2DArray warp_color;
layout(r32f, binding = IMAGE_WARP_DEPTH) uniform writeonly image2DArray warp_depth;
layout(std430, binding = SSBO_WARP_COUNTS) restrict buffer WarpCounts { uvec4 warp_counts[]; };
uniform int warp_layer;
uniform float warp_thickness;  // relative depth: how far behind a surface a hit may be and still be on it

shared uint group_counts[4];

// Linear view depth in the eye (slot 1) of the scene-local point `p`.
float eye_depth_of(vec3 p) { return -(transpose(eye_rotation[1]) * (p - eye_position[1])).z; }

void main() {
    uint li = gl_LocalInvocationIndex;
    if (li < 4u) group_counts[li] = 0u;
    barrier();
    ivec2 size = qt_level[0].xy;
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    bool inside = all(lessThan(p, size));
    uint kind = 4u;  // 0 disocclusion, 1 off screen, 2 hit, 4 background / outside
    uint nodes = 0u;
    if (inside) {
        vec3 o, d;
        camera_ray(1, vec2(p) + 0.5, vec2(size), o, d);
        QtResult h = qt_trace(0, o, d);
        nodes = h.nodes;
        ivec2 src = clamp(ivec2(floor(h.point.xy)), ivec2(0), size - 1);
        float depth = 0.0;
        if (h.status == QT_HIT) {
            src = h.pixel;
            vec4 surface = texelFetch(gb_position, ivec3(src, 0), 0);  // xyz scene-local, w view depth
            float zs = eye_depth.x / surface.w;
            kind = h.point.z >= zs * (1.0 - warp_thickness) ? 2u : 0u;
            if (kind == 0u) {
                QtRay r = qt_screen_ray(0, o, d);
                float u = dot(h.point.xy - r.s0.xy, r.sd.xy);  // |sd.xy| = 1 or 0 (line of sight)
                ivec2 back = ivec2(floor((r.s0 + (u - 1.0) * r.sd).xy));
                if (all(greaterThanEqual(back, ivec2(0))) && all(lessThan(back, size))) {
                    float wb = texelFetch(gb_position, ivec3(back, 0), 0).w;
                    // the ray was in front of that pixel's surface (or it is background)
                    if (wb == 0.0 || r.s0.z + (u - 1.0) * r.sd.z >= eye_depth.x / wb * (1.0 - warp_thickness))
                        src = back;
                }
                vec4 fill = texelFetch(gb_position, ivec3(src, 0), 0);
                depth = fill.w > 0.0 ? eye_depth_of(fill.xyz) : 0.0;
            } else {
                // The exact crossing: the point on the eye's ray at the hit's central view depth.
                mat3 to_view = transpose(eye_rotation[0]);
                float da = -(to_view * (o - eye_position[0])).z, dd = -(to_view * d).z;
                float t = dd != 0.0 ? (eye_depth.x / h.point.z - da) / dd : 0.0;
                depth = eye_depth_of(o + t * d);
            }
        } else if (h.status == QT_OFFSCREEN || h.status == QT_NEAR) {
            kind = 1u;
            vec4 fill = texelFetch(gb_position, ivec3(src, 0), 0);
            depth = fill.w > 0.0 ? eye_depth_of(fill.xyz) : 0.0;
        }
        vec4 c = imageLoad(center_ldr, ivec3(src, 0));
        imageStore(warp_color, ivec3(p, warp_layer), vec4(c.rgb, kind < 2u ? 0.0 : 1.0));
        imageStore(warp_depth, ivec3(p, warp_layer), vec4(max(depth, 0.0)));
        if (kind < 3u) atomicAdd(group_counts[kind], 1u);
        atomicAdd(group_counts[3], nodes);
    }
    barrier();
    if (li < 4u && group_counts[li] > 0u) atomicAdd(warp_counts[warp_layer][li], group_counts[li]);
}
