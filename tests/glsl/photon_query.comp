#version 430
// Radius queries for the tests (tests/photon_gpu.py): the photons within
// query_radius of each query point through the hash grid (QUERY_KDTREE 0) or the kd-tree (1),
// written as indices into the searched array: found[q * query_capacity + j], the count (which may
// exceed the capacity) to counts[q].
#include "layout.glsl"  // PHOTON_QUERY_GROUP: tests/photon_gpu.py
layout(local_size_x = PHOTON_QUERY_GROUP) in;
#include "photon/grid.glsl"  // rayvr/glsl/photon: the loader falls back to rayvr's shaders
#include "photon/kdtree.glsl"

layout(std430, binding = SSBO_PHOTON_QUERIES) readonly restrict buffer Queries { vec4 queries[]; };
layout(std430, binding = SSBO_PHOTON_FOUND) writeonly restrict buffer Found { uint found[]; };
layout(std430, binding = SSBO_PHOTON_QUERY_COUNTS) writeonly restrict buffer Counts { uint counts[]; };

uniform uint query_count;
uniform uint query_capacity;
uniform float query_radius;

uint q_index;
uint q_found;

float photon_search_r2() { return query_radius * query_radius; }

void photon_visit(uint index, Photon p, float d2) {
    if (q_found < query_capacity) found[q_index * query_capacity + q_found] = index;
    ++q_found;
}

void main() {
    q_index = gl_GlobalInvocationID.x;
    if (q_index >= query_count) return;
    q_found = 0u;
#ifndef QUERY_KDTREE
#define QUERY_KDTREE 0
#endif
#if QUERY_KDTREE
    kdtree_search(queries[q_index].xyz);
#else
    grid_search(queries[q_index].xyz);
#endif
    counts[q_index] = q_found;
}
