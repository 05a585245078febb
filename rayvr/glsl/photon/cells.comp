#version 430
// The hash grid's cells (frame/effects/photon/cells.py): CELLS_STAGE 0 zeroes the counts (cells + 2
// words: the cells, the empty slots' bin, the total); CELLS_STAGE 1 gives every photon slot its
// key (cell index, or grid_dead_key() for an empty slot, so empty slots sort last) with its slot
// index, and counts the photons per cell. Integer atomics: the counts are exact and deterministic.
#include "../layout.glsl"  // PHOTON_CELLS_GROUP: rayvr/frame/effects/photon/cells.py
layout(local_size_x = PHOTON_CELLS_GROUP) in;
#include "photon.glsl"

layout(std430, binding = SSBO_PHOTONS) readonly restrict buffer Photons { Photon photons[]; };
layout(std430, binding = SSBO_PHOTON_KEYS) writeonly restrict buffer Keys { uvec2 keys[]; };
layout(std430, binding = SSBO_PHOTON_SCAN) restrict buffer Counts { uint counts[]; };

uniform uint item_count;

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(PHOTON_CELLS_GROUP);
    if (i >= item_count) return;
#ifndef CELLS_STAGE
#define CELLS_STAGE 1
#endif
#if CELLS_STAGE == 0
    counts[i] = 0u;
#else
    Photon p = photons[i];
    uint key = photon_extra(p) != 0u ? grid_cell(photon_position(p)) : grid_dead_key();
    keys[i] = uvec2(key, i);
    atomicAdd(counts[key], 1u);
#endif
}
