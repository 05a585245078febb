#version 430
// Thin-lens depth of field through screen-space rays (Widmer et al. 2015 §5.2; frame/passes/dof.py):
// per pixel, `dof_samples` rays from points of the lens disk (diameter dof_diameter, in the eye's
// view plane) through the pixel ray's point at view depth dof_focus, traced through the frame's
// quadtree (qt_trace_layers, one layer, slabs of dof_thickness); each gathers the frame's colour
// where it meets the screen: the hit pixel, the near side of an occlusion (inpainting), else where
// it leaves the image or reaches infinity. The mean is the pixel's colour. Lens points come from
// the surface point's random stream (common/random.glsl): both eyes draw the same for it.
#ifndef HDR_FORMAT
#define HDR_FORMAT rgba16f
#endif
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/camera.glsl"
#include "../common/gbuffer.glsl"
#include "../common/random.glsl"
#include "../ssrt/quadtree.glsl"

layout(HDR_FORMAT, binding = IMAGE_DOF_IN) uniform readonly image2DArray dof_in;
layout(rgba32f, binding = IMAGE_DOF_OUT) uniform writeonly image2DArray dof_out;
uniform float dof_diameter;   // lens diameter, scene units
uniform float dof_focus;      // view depth in focus, scene units
uniform int dof_samples;
uniform float dof_thickness;  // relative depth of each surface's slab
uniform uint frame_seed;

// concentric_disk (Shirley & Chiu's map of [0, 1)^2 onto the unit disk): cameras/sampling.glsl,
// through common/camera.glsl.

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 size = imageSize(dof_out).xy;
    if (any(greaterThanEqual(p.xy, size))) return;
    vec3 o, d;
    if (!camera_ray(p.z, vec2(p.xy) + 0.5, vec2(size), o, d)) {
        imageStore(dof_out, p, imageLoad(dof_in, p));
        return;
    }
    vec3 focus = o + d * (dof_focus / dot(d, eye_forward(p.z)));
    vec4 position = texelFetch(gb_position, p, 0);
    vec4 t = eye_tangents[p.z];
    vec3 seed_point = position.w > 0.0 ? position.xyz : focus;
    float depth = position.w > 0.0 ? position.w : dof_focus;
    uint rng = rng_seed_surface(seed_point, depth * (t.w - t.z) / float(size.y), frame_seed);
    vec3 sum = vec3(0.0);
    int n = max(dof_samples, 1);
    for (int i = 0; i < n; ++i) {
        vec2 l = concentric_disk(rng_next2(rng)) * (0.5 * dof_diameter);
        vec3 lens = o + eye_rotation[p.z] * vec3(l, 0.0);
        QtResult r = qt_trace_layers(p.z, lens, focus - lens, 1, dof_thickness);
        ivec2 at = (r.status == QT_HIT || r.status == QT_OCCLUDED) && r.pixel.x >= 0
            ? r.pixel : clamp(ivec2(floor(r.point.xy)), ivec2(0), size - 1);
        sum += imageLoad(dof_in, ivec3(at, p.z)).rgb;
    }
    imageStore(dof_out, p, vec4(sum / float(n), 1.0));
}
