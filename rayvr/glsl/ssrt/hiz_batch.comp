#version 430
// Trace a batch of rays with hiz_trace (ssrt/hiz.glsl) through a built min-max pyramid, for tests
// and benchmarks (rayvr/bench/tracers/hiz.py HizTracer). The layout of ssrt/dda_batch.comp: rays at
// SSBO_HIZ_RAYS, per ray vec4(origin, eye layer as a float), vec4(direction, unused), scene-local;
// results at SSBO_HIZ_RESULTS, per ray uvec4(status, iterations, pixel x, pixel y as int bits),
// uvec4(point in S as float bits, 0).
#include "../layout.glsl"
#define LOCAL_SIZE SSRT_RAY_GROUP  // rayvr/gl/gpu_layout.py: the Python side dispatches by it
layout(local_size_x = LOCAL_SIZE) in;

#include "hiz.glsl"

layout(std430, binding = SSBO_HIZ_RAYS) readonly restrict buffer HizRays { vec4 hiz_rays[]; };
layout(std430, binding = SSBO_HIZ_RESULTS) writeonly restrict buffer HizResults { uvec4 hiz_results[]; };

uniform uint ray_count;
uniform int start_level;
uniform int max_iterations;
uniform float thickness_factor;  // 1 / (1 + thickness); 0: infinite thickness
uniform bool skip_origin;        // start where the ray leaves its origin's pixel

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * LOCAL_SIZE;
    if (i >= ray_count)
        return;
    vec4 a = hiz_rays[2 * i];
    vec4 b = hiz_rays[2 * i + 1];
    HizResult r = hiz_trace(int(a.w), a.xyz, b.xyz, start_level, max_iterations, thickness_factor,
                            skip_origin);
    hiz_results[2 * i] = uvec4(r.status, r.iterations, uvec2(r.pixel));
    hiz_results[2 * i + 1] = uvec4(floatBitsToUint(r.point), 0u);
}
