#version 430
// Exclusive prefix sum in place over scan_data[scan_base .. scan_base + item_count) (frame/passes/
// prefix_scan.py runs it level by level: counts -> start indices, and the radix sort's digit
// table). SCAN_STAGE 0: each group scans a block of SCAN_BLOCK words (SCAN_ITEMS per invocation,
// then a Hillis-Steele scan of the invocation totals in shared memory) and writes the block's
// total to scan_data[sums_base + block]; the host scans those totals the same way, one level up.
// SCAN_STAGE 1: adds each block's scanned total to its words.
#include "../layout.glsl"  // SCAN_GROUP, SCAN_ITEMS, SCAN_BLOCK: rayvr/frame/passes/prefix_scan.py
layout(local_size_x = SCAN_GROUP) in;

layout(std430, binding = SSBO_PHOTON_SCAN) restrict buffer ScanData { uint scan_data[]; };

uniform uint scan_base;
uniform uint sums_base;
uniform uint item_count;

shared uint partial[2][SCAN_GROUP];

uint block_index() { return gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x; }

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    uint first = block * uint(SCAN_BLOCK) + t * uint(SCAN_ITEMS);
#ifndef SCAN_STAGE
#define SCAN_STAGE 0
#endif
#if SCAN_STAGE == 0
    uint v[SCAN_ITEMS];
    uint sum = 0u;
    for (int j = 0; j < SCAN_ITEMS; ++j) {
        uint k = first + uint(j);
        v[j] = k < item_count ? scan_data[scan_base + k] : 0u;
        uint x = v[j];
        v[j] = sum;
        sum += x;
    }
    partial[0][t] = sum;
    barrier();
    int src = 0;
    for (uint step = 1u; step < uint(SCAN_GROUP); step <<= 1) {
        uint x = partial[src][t];
        if (t >= step) x += partial[src][t - step];
        partial[1 - src][t] = x;
        src = 1 - src;
        barrier();
    }
    uint before = partial[src][t] - sum;  // inclusive -> exclusive
    for (int j = 0; j < SCAN_ITEMS; ++j) {
        uint k = first + uint(j);
        if (k < item_count) scan_data[scan_base + k] = before + v[j];
    }
    if (t == uint(SCAN_GROUP - 1)) scan_data[sums_base + block] = partial[src][t];
#else
    uint add = scan_data[sums_base + block];
    for (int j = 0; j < SCAN_ITEMS; ++j) {
        uint k = first + uint(j);
        if (k < item_count) scan_data[scan_base + k] += add;
    }
#endif
}
