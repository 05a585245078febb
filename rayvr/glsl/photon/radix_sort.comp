#version 430
// Stable LSD radix sort of (key, slot) pairs by key, 8 bits a round (frame/passes/radix_sort.py).
//   SORT_STAGE 0  histogram: each group of SORT_GROUP pairs counts its digits; the count of digit
//                 d in group g goes to table[d * groups + g] (digit-major, so that the exclusive
//                 scan of the table, glsl/photon/scan.comp, is every pair's first destination)
//   SORT_STAGE 1  scatter: a pair goes to table[d * groups + g] + the number of pairs before it in
//                 its group with the same digit (stable, deterministic): the digit counts of the
//                 earlier chunks of 32 pairs (shared-memory histograms) plus a count within its chunk
//   SORT_STAGE 2  permute (the photon map only): photon_map[i] = photons[slot of the i-th sorted pair]
// SORT_COUNTED 1: the pairs are the first sort_count[sort_count_slot].w (at most item_count, which
// sizes the dispatch), a count the GPU wrote (the wavefront's rays: frame/passes/ray_order.py);
// the pairs past it are neither read nor written.
#include "../layout.glsl"  // SORT_GROUP, SORT_RADIX: rayvr/frame/passes/radix_sort.py
#ifndef SORT_STAGE
#define SORT_STAGE 0
#endif
#ifndef SORT_COUNTED
#define SORT_COUNTED 0
#endif
layout(local_size_x = SORT_GROUP) in;
#include "photon.glsl"

layout(std430, binding = SSBO_PHOTON_KEYS) readonly restrict buffer KeysIn { uvec2 keys_in[]; };
layout(std430, binding = SSBO_PHOTON_KEYS_ALT) writeonly restrict buffer KeysOut { uvec2 keys_out[]; };
layout(std430, binding = SSBO_PHOTON_SCAN) restrict buffer Table { uint table[]; };
layout(std430, binding = SSBO_PHOTONS) readonly restrict buffer Photons { Photon photons[]; };
layout(std430, binding = SSBO_PHOTON_MAP) writeonly restrict buffer PhotonMap { Photon photon_map[]; };

uniform uint item_count;
uniform uint digit_shift;
#if SORT_COUNTED
layout(std430, binding = SSBO_SORT_COUNT) readonly restrict buffer SortCount { uvec4 sort_count[]; };
uniform uint sort_count_slot;
#endif

#define SORT_CHUNK 32
shared uint digits[SORT_GROUP];
#if SORT_STAGE == 1
shared uint chunk_counts[SORT_GROUP / SORT_CHUNK][SORT_RADIX];
#endif

void main() {
    uint g = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y;
    uint t = gl_LocalInvocationID.x;
    uint i = g * uint(SORT_GROUP) + t;
#if SORT_COUNTED
    uint pairs = min(item_count, sort_count[sort_count_slot].w);
#else
    uint pairs = item_count;
#endif
#if SORT_STAGE == 2
    if (i < pairs) photon_map[i] = photons[keys_in[i].y];
#else
    uvec2 kv = i < pairs ? keys_in[i] : uvec2(0u);
    uint d = i < pairs ? (kv.x >> digit_shift) & (SORT_RADIX - 1u) : SORT_RADIX;
#if SORT_STAGE == 0
    digits[t] = 0u;
    barrier();
    if (d < SORT_RADIX) atomicAdd(digits[d], 1u);
    barrier();
    table[t * groups + g] = digits[t];
#else
    for (int c = 0; c < SORT_GROUP / SORT_CHUNK; ++c) chunk_counts[c][t] = 0u;
    digits[t] = d;
    barrier();
    uint chunk = t / uint(SORT_CHUNK);
    if (d < SORT_RADIX) atomicAdd(chunk_counts[chunk][d], 1u);  // counts: the same whatever the order
    barrier();
    if (d < SORT_RADIX) {
        uint rank = 0u;
        for (uint c = 0u; c < chunk; ++c) rank += chunk_counts[c][d];
        for (uint j = chunk * uint(SORT_CHUNK); j < t; ++j) rank += digits[j] == d ? 1u : 0u;
        keys_out[table[d * groups + g] + rank] = kv;
    }
#endif
#endif
}
