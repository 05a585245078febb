#version 430
// Debugging tool for any camera model: writes every sample's camera ray, as the model's GLSL
// makes it (common/camera.glsl with the model's defines()), into an SSBO, so it can be compared with the
// model's numpy reference (rayvr/frame/cameras/*.py rays(); tests/test_cameras.py does).
// Build: shaders.compute(ctx, "cameras/camera_rays.comp", model.defines() + CAMERA_SUBSAMPLES);
// set the per-eye uniforms (model.uniforms(eyes, origin)), camera_channel, subsample (-1: the
// central ray, else sub-ray i) and image_size; run ceil(w/8) x ceil(h/8) x eyes groups.
// Output, per eye, per GL row (bottom-up), per column: 4 vec4s
//   origin (scene-local) + valid (1 or 0), direction + footprint, direction_x, direction_y (the neighbours).
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/camera.glsl"

uniform ivec2 image_size;
uniform int subsample;
layout(std430, binding = 0) writeonly buffer CameraRaysOut { vec4 rays_out[]; };

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p.xy, image_size))) return;
    vec2 size = vec2(image_size), pixel = vec2(p.xy) + 0.5;
    vec3 origin, direction, direction_x, direction_y;
    bool valid;
    if (subsample < 0) {
        valid = camera_ray(p.z, pixel, size, origin, direction);
        camera_ray_neighbours(p.z, pixel, size, direction_x, direction_y);
    } else {
        valid = camera_subray(p.z, pixel, size, uint(subsample), origin, direction);
        camera_subray_neighbours(p.z, pixel, size, uint(subsample), direction_x, direction_y);
    }
    int i = 4 * ((p.z * image_size.y + p.y) * image_size.x + p.x);
    rays_out[i] = vec4(origin, valid ? 1.0 : 0.0);
    rays_out[i + 1] = vec4(direction, camera_footprint(p.z, pixel, size));
    rays_out[i + 2] = vec4(direction_x, 0.0);
    rays_out[i + 3] = vec4(direction_y, 0.0);
}
