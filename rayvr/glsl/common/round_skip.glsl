// Pixels an MSAA round leaves alone (frame/passes/primary_rays.py): the select gives them the sample
// weight ROUND_SKIPPED (< 0; gl/gpu_layout.py) when the round has nothing for them (a round past their last slot, or an
// empty slot above 0); they add nothing, and their G-buffer stays what an earlier round of the
// frame made, so the round's gbuffer resolve, shade, classify and sample_accumulate skip them.
// ROUND_SKIP 1: the pass reads the weights (frames of MSAA rounds); 0: no pixel is skipped.
#include "../layout.glsl"
#ifndef ROUND_SKIP
#define ROUND_SKIP 0
#endif
#if ROUND_SKIP
layout(r32f, binding = IMAGE_SAMPLE_WEIGHT) uniform readonly image2DArray round_weight;
bool round_skips(ivec3 p) { return imageLoad(round_weight, p).x < 0.0; }
#else
bool round_skips(ivec3 p) { return false; }
#endif

// ROUND_TILES 1 (frame/passes/round_gate.py): the round's select lists the PIXEL_TILE tiles that hold a
// pixel the round does not leave alone, and the round's per-pixel passes may run over that list only
// (round_listed 1: an indirect dispatch of one workgroup a listed tile, round_gate.comp's size): most
// of an MSAA round's pixels are skipped, and a pass over the whole frame cost ~0.05 ms on the GPU
// to skip them. round_pixel() is the invocation's pixel either way (past the list: outside every image).
#ifndef ROUND_TILES
#define ROUND_TILES 0
#endif
#if ROUND_TILES
layout(std430, binding = SSBO_ROUND_TILES) restrict buffer RoundTiles {
    uvec4 round_tile_args;  // the listed passes' dispatch size; w: the tiles listed
    uint round_tile_count;  // the select's running count (round_gate.comp moves it to the args)
    uint round_tile_every;  // 1: most tiles are listed, the dispatch is the whole frame's grid
    uint round_tiles[];     // tile x | y << 14 | layer << 28
};
uniform int round_listed;
ivec3 round_pixel() {
    if (round_listed == 0 || round_tile_every != 0u)
        return ivec3(gl_GlobalInvocationID);
    uint g = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (g >= round_tile_args.w)
        return ivec3(1 << 30);
    uint t = round_tiles[g];
    return ivec3(ivec2(t & 0x3FFFu, (t >> 14) & 0x3FFFu) * PIXEL_TILE + ivec2(gl_LocalInvocationID.xy), int(t >> 28));
}
#else
ivec3 round_pixel() { return ivec3(gl_GlobalInvocationID); }
#endif
