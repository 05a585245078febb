#version 430
// Trace a batch of rays with qt_trace (ssrt/quadtree.glsl) through a built quadtree, for tests and
// benchmarks (rayvr/frame/passes/quadtree.py QuadtreeTracer). The same layout as ssrt/dda_batch.comp:
// rays at SSBO_QUADTREE_RAYS, per ray vec4(origin, eye layer as a float), vec4(direction, unused),
// scene-local; results at SSBO_QUADTREE_RESULTS, per ray uvec4(status, nodes tested, pixel x,
// pixel y as int bits), uvec4(point in S as float bits, depth layer hit as int bits). Traced with
// qt_trace_layers through `trace_layers` depth layers, slabs of relative `trace_thickness`.
#include "../layout.glsl"
#define LOCAL_SIZE SSRT_RAY_GROUP  // rayvr/gl/gpu_layout.py: the Python side dispatches by it
layout(local_size_x = LOCAL_SIZE) in;

#include "quadtree.glsl"

layout(std430, binding = SSBO_QUADTREE_RAYS) readonly restrict buffer QtRays { vec4 qt_rays[]; };
layout(std430, binding = SSBO_QUADTREE_RESULTS) writeonly restrict buffer QtResults { uvec4 qt_results[]; };

uniform uint ray_count;
uniform int trace_layers = 1;
uniform float trace_thickness = QT_INF;

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * LOCAL_SIZE;
    if (i >= ray_count)
        return;
    vec4 a = qt_rays[2 * i];
    vec4 b = qt_rays[2 * i + 1];
    QtResult r = qt_trace_layers(int(a.w), a.xyz, b.xyz, trace_layers, trace_thickness);
    qt_results[2 * i] = uvec4(r.status, r.nodes, uvec2(r.pixel));
    qt_results[2 * i + 1] = uvec4(floatBitsToUint(r.point), uint(r.layer));
}
