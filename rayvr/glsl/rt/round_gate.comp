#version 430
// The round gate (frame/passes/round_gate.py): whether MSAA round `msaa_round` of a colour channel
// set lies within the set's count (msaa_count, the trace's; one round at least), as dispatch sizes
// for the round's passes: each grid of gate_grids where it does, none where it does not. Where it
// does not, the traced effects' pixel lists are emptied too (GATE_LISTS), so their passes, which
// dispatch from the lists, trace nothing either: without it they would trace the round before's
// list again, which classify left there.
layout(local_size_x = 1) in;
#include "../layout.glsl"
#ifndef GATE_LISTS
#define GATE_LISTS 0
#endif
#if GATE_LISTS
#include "pixel_list.glsl"
#endif
layout(std430, binding = SSBO_MSAA_COUNT) readonly buffer MsaaCount { uint msaa_count; };
layout(std430, binding = SSBO_ROUND_GATE) writeonly buffer RoundGate { uvec4 gate_args[]; };
uniform int msaa_round;
uniform int gate_grid_count;
uniform uvec3 gate_grids[GATE_GRIDS];

void main() {
    bool within = uint(msaa_round) < max(msaa_count, 1u);
    for (int i = 0; i < gate_grid_count; ++i)
        gate_args[i] = within ? uvec4(gate_grids[i], 0u) : uvec4(0u, 1u, 1u, 0u);
#if GATE_LISTS
    if (!within)
        for (uint s = 0u; s < uint(RT_SLOTS); ++s)
            rt_args[s] = uvec4(0u, 1u, 1u, 0u);
#endif
}
