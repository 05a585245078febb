#version 430
// The sampled frame's colour for display (frame/passes/sample_resolve.py): the accumulated sum,
// through the camera model's resolve (CameraModel.reconstruction, CAMERA_RESOLVE_FILE): a sparse
// model's file fills the pixels between its samples; without one, cameras/dense_resolve.glsl
// writes the sum as it is. The pass dispatches the program once per entry of the model's
// resolve_steps(), setting that entry's uniforms; the last dispatch writes `frame_hdr` everywhere.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/camera.glsl"

layout(rgba32f, binding = IMAGE_SAMPLE_SUM) uniform readonly image2DArray sum;
layout(rgba16f, binding = IMAGE_FRAME_HDR) uniform writeonly image2DArray frame_hdr;
// A sparse model's scratch between its dispatches (the pass makes it only for sparse models).
layout(rgba32f, binding = IMAGE_SAMPLE_FILL) uniform image2DArray fill;
uniform float exposure;  // what tonemap multiplies by

// For a fill in the units tonemap displays, y = x / (1 + x) of the exposed colour x, and back:
// in linear HDR a light's samples outweigh every dark sample beside them.
vec3 compress(vec3 c) { vec3 x = max(c, 0.0) * exposure; return x / (1.0 + x); }
vec3 expand(vec3 y) { return y / max(1.0 - y, 1e-7) / exposure; }

bool is_sample(int eye, ivec2 q, vec2 size) { return camera_footprint(eye, vec2(q) + 0.5, size) > 0.0; }

// The model's part: void camera_resolve(ivec3 p, ivec2 n), pixel p.xy of eye layer p.z of n.
#include CAMERA_RESOLVE_FILE or "../cameras/dense_resolve.glsl"

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 n = imageSize(sum).xy;
    if (any(greaterThanEqual(p.xy, n))) return;
    camera_resolve(p, n);
}
