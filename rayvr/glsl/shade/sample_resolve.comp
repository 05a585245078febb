#version 430
// The sampled frame's colour for display (passes/sample_resolve.py): the accumulated sum, and
// with RECONSTRUCT (foveated) the pixels between samples filled bilinearly from the corners of
// the finest dither-lattice cell around them whose corners are all samples (cameras/foveated.py
// reconstruct is the numpy twin).
#ifndef RECONSTRUCT
#define RECONSTRUCT 0
#endif
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "../layout.glsl"
#include "../common/camera.glsl"

layout(rgba32f, binding = IMAGE_SAMPLE_SUM) uniform readonly image2DArray sum;
layout(rgba16f, binding = IMAGE_FRAME_HDR) uniform writeonly image2DArray frame_hdr;

bool is_sample(int eye, ivec2 q, vec2 size) { return camera_footprint(eye, vec2(q) + 0.5, size) > 0.0; }

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 n = imageSize(sum).xy;
    if (any(greaterThanEqual(p.xy, n))) return;
    vec3 c = imageLoad(sum, p).rgb;
#if RECONSTRUCT
    vec2 size = vec2(n);
    if (!is_sample(p.z, p.xy, size)) {
        for (int k = 1; k <= 6; k++) {
            int s = 1 << k;
            ivec2 q0 = (p.xy / s) * s, q1 = min(q0 + s, n - 1);
            if (is_sample(p.z, q0, size) && is_sample(p.z, ivec2(q1.x, q0.y), size) &&
                is_sample(p.z, ivec2(q0.x, q1.y), size) && is_sample(p.z, q1, size)) {
                vec2 a = vec2(q1.x != q0.x ? float(p.x - q0.x) / float(q1.x - q0.x) : 0.0,
                              q1.y != q0.y ? float(p.y - q0.y) / float(q1.y - q0.y) : 0.0);
                vec3 c00 = imageLoad(sum, ivec3(q0, p.z)).rgb, c10 = imageLoad(sum, ivec3(q1.x, q0.y, p.z)).rgb;
                vec3 c01 = imageLoad(sum, ivec3(q0.x, q1.y, p.z)).rgb, c11 = imageLoad(sum, ivec3(q1, p.z)).rgb;
                c = mix(mix(c00, c10, a.x), mix(c01, c11, a.x), a.y);
                break;
            }
        }
    }
#endif
    imageStore(frame_hdr, p, vec4(c, 1.0));
}
