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
