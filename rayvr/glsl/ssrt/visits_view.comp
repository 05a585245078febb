#version 430
// Debug view "quadtree_visits" (paper Fig. 1c/10): each covered pixel's mirror ray traced through
// the screen-space quadtree of its eye (ssrt/quadtree.glsl); red = nodes tested (exact, up to 255),
// green/blue = a heat ramp of the same count over 0..64; background black.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/gbuffer.glsl"
#include "quadtree.glsl"

layout(rgba8, binding = IMAGE_LDR) uniform writeonly image2DArray ldr_out;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p.xy, imageSize(ldr_out).xy))) return;
    Surface s = gbuffer_fetch(p);
    vec3 c = vec3(0.0);
    if (s.triangle != NO_HIT) {
        vec3 v = normalize(s.position - eye_position[p.z]);
        vec3 d = reflect(v, s.normal);
        // Off the surface by a hair of its view depth: the ray must not start behind its own plane.
        QtResult r = qt_trace(p.z, s.position + s.normal * (1e-4 * s.view_depth), d);
        float n = float(r.nodes);
        c = vec3(min(n, 255.0) / 255.0, clamp(n / 64.0, 0.0, 1.0), clamp(1.0 - n / 64.0, 0.0, 1.0));
    }
    imageStore(ldr_out, p, vec4(c, 1.0));
}
