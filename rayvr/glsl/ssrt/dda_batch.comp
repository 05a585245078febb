#version 430
// Trace a batch of rays with dda_trace (ssrt/dda.glsl) against a frame's G-buffer, for tests and
// benchmarks (rayvr/bench/tracers/dda.py DdaTracer). Rays at SSBO_DDA_RAYS: per ray vec4(origin, eye
// layer as a float), vec4(direction, unused), scene-local. Results at SSBO_DDA_RESULTS: per ray
// uvec4(status, steps, pixel x, pixel y as int bits), uvec4(point in S as float bits, 0).
#include "../layout.glsl"
#define LOCAL_SIZE SSRT_RAY_GROUP  // rayvr/gl/gpu_layout.py: the Python side dispatches by it
layout(local_size_x = LOCAL_SIZE) in;

#include "dda.glsl"

layout(std430, binding = SSBO_DDA_RAYS) readonly restrict buffer DdaRays { vec4 dda_rays[]; };
layout(std430, binding = SSBO_DDA_RESULTS) writeonly restrict buffer DdaResults { uvec4 dda_results[]; };

uniform uint ray_count;
uniform int max_steps;
uniform float stride;
uniform float thickness_factor;  // 1 / (1 + thickness); 0: infinite thickness

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * LOCAL_SIZE;
    if (i >= ray_count)
        return;
    vec4 a = dda_rays[2 * i];
    vec4 b = dda_rays[2 * i + 1];
    int eye = int(a.w);
    vec2 size = vec2(textureSize(dda_linear_depth, 0).xy);
    DdaResult r = dda_trace(eye, a.xyz, b.xyz, size, max_steps, stride, thickness_factor);
    dda_results[2 * i] = uvec4(r.status, r.steps, uvec2(r.pixel));
    dda_results[2 * i + 1] = uvec4(floatBitsToUint(r.point), 0u);
}
