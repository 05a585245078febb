#version 430
// The round gate (frame/passes/round_gate.py), one invocation.
// GATE_TILES 0, before a round's select: whether MSAA round `msaa_round` of a colour channel set lies
// within the set's count (msaa_count, the trace's; one round at least), as dispatch sizes for the
// round's frame-wide passes: each grid of gate_grids where it does, none where it does not. Where it
// does not, the traced effects' pixel lists are emptied too (GATE_LISTS), so their passes, which
// dispatch from the lists, trace nothing either: without it they would trace the round before's
// list again, which classify left there.
// GATE_TILES 1, after the select: the dispatch size of the passes that run over the select's list of
// tiles (common/round_skip.glsl ROUND_TILES), one workgroup a tile, rows of at most 65535 (GL's
// least limit a dimension); where more than half the frame's tiles are listed, the frame's own
// grid instead (the list is in no order: a round of every pixel ran 0.04-0.05 ms slower a pass
// over it on the GPU); the select's running count restarts for the next round.
layout(local_size_x = 1) in;
#include "../layout.glsl"
#ifndef GATE_LISTS
#define GATE_LISTS 0
#endif
#ifndef GATE_TILES
#define GATE_TILES 0
#endif
#if GATE_TILES
#include "../common/round_skip.glsl"  // (with ROUND_TILES 1)
uniform uvec3 round_grid;  // the frame's per-pixel grid
#else
#if GATE_LISTS
#include "pixel_list.glsl"
#endif
layout(std430, binding = SSBO_MSAA_COUNT) readonly buffer MsaaCount { uint msaa_count; };
layout(std430, binding = SSBO_ROUND_GATE) writeonly buffer RoundGate { uvec4 gate_args[]; };
uniform int msaa_round;
uniform int gate_grid_count;
uniform uvec3 gate_grids[GATE_GRIDS];
#endif

void main() {
#if GATE_TILES
    uint n = round_tile_count;
    round_tile_count = 0u;
    bool every = 2u * n > round_grid.x * round_grid.y * round_grid.z;
    round_tile_every = every ? 1u : 0u;
    round_tile_args = every ? uvec4(round_grid, n) : uvec4(min(n, 65535u), max((n + 65534u) / 65535u, 1u), 1u, n);
#else
    bool within = uint(msaa_round) < max(msaa_count, 1u);
    for (int i = 0; i < gate_grid_count; ++i)
        gate_args[i] = within ? uvec4(gate_grids[i], 0u) : uvec4(0u, 1u, 1u, 0u);
#if GATE_LISTS
    if (!within)
        for (uint s = 0u; s < uint(RT_SLOTS); ++s)
            rt_args[s] = uvec4(0u, 1u, 1u, 0u);
#endif
#endif
}
