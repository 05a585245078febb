#version 430
// Classify: append each pixel whose effect is ray traced to that effect's list (rt/pixel_list.glsl),
// and turn the counts into indirect dispatch sizes, all in one dispatch.
//
// A work group covers CLASSIFY_GROUP_X x CLASSIFY_GROUP_Y pixels (multiples of 8) as 8x8 tiles, each
// tile 64 consecutive invocations, so a wave of 32 covers an 8x4 block and a group's entries land
// as one run of the list (coherent rays in the effect passes). Aggregation, per list:
//   CLASSIFY_BALLOT 1 (GL_KHR_shader_subgroup_ballot) or 2 (GL_ARB_shader_ballot): a ballot gives
//     each lane its place within its wave; one shared atomic per wave, one global atomic per group;
//   CLASSIFY_BALLOT 0: one shared atomic per pixel, one global atomic per group.
// The global atomics count into rt_running; the last group to finish (a ticket counter) writes
// rt_args (dispatch size and count) and zeroes rt_running and the ticket for the next frame, so
// the pass needs no clear from the CPU and no second dispatch. The order within a list is not
// deterministic (the effect passes do not depend on it: each entry writes only its own pixel and
// seeds its random numbers from the pixel).
#ifndef CLASSIFY_BALLOT
#define CLASSIFY_BALLOT 0
#endif
#ifndef CLASSIFY_GROUP_X  // rayvr/passes/raytrace.py ClassifyPass passes all three (430: literals)
#define CLASSIFY_GROUP_X 32
#define CLASSIFY_GROUP_Y 16
#define CLASSIFY_INVOCATIONS 512
#endif
#if CLASSIFY_BALLOT == 1
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#elif CLASSIFY_BALLOT == 2
#extension GL_ARB_shader_ballot : require
#extension GL_ARB_gpu_shader_int64 : require
#endif
#include "pixel_list.glsl"
#include "../common/gbuffer.glsl"
#include "../common/round_skip.glsl"
#ifdef STEREO_REUSE
#include "../stereo/reuse.glsl"
#endif

layout(local_size_x = CLASSIFY_INVOCATIONS, local_size_y = 1, local_size_z = 1) in;

const int SLOT_OF_EFFECT[MAX_EFFECT_ID] = RT_SLOT_TABLE;  // effect ID -> list slot, -1: not traced
shared uint group_count[RT_SLOTS];
shared uint group_base[RT_SLOTS];

// The pixel of invocation `li`: 8x8 tiles in row order across the group, rows within a tile.
ivec3 classify_pixel(uint li) {
    uint tile = li >> 6, within = li & 63u;
    uvec2 t = uvec2(tile % uint(CLASSIFY_GROUP_X / 8), tile / uint(CLASSIFY_GROUP_X / 8));
    uvec2 o = t * 8u + uvec2(within & 7u, within >> 3);
    return ivec3(gl_WorkGroupID.xy * uvec2(CLASSIFY_GROUP_X, CLASSIFY_GROUP_Y) + o, gl_WorkGroupID.z);
}

#if CLASSIFY_BALLOT != 0
// This lane's place among the lanes of its wave on list `s` (in == this lane is on it); the wave's
// leader reserves the wave's run of the group's entries with one shared atomic.
uint wave_place(uint s, bool in_list) {
#if CLASSIFY_BALLOT == 1
    uvec4 b = subgroupBallot(in_list);
    uint before = subgroupBallotExclusiveBitCount(b), n = subgroupBallotBitCount(b);
    uint first = 0u;
    if (subgroupElect() && n > 0u) first = atomicAdd(group_count[s], n);
    return subgroupBroadcastFirst(first) + before;
#else
    uvec2 b = unpackUint2x32(ballotARB(in_list));
    uvec2 lt = unpackUint2x32(gl_SubGroupLtMaskARB);
    uint before = uint(bitCount(b.x & lt.x) + bitCount(b.y & lt.y));
    uint n = uint(bitCount(b.x) + bitCount(b.y));
    uint first = 0u;
    if (readFirstInvocationARB(gl_SubGroupInvocationARB) == gl_SubGroupInvocationARB && n > 0u)
        first = atomicAdd(group_count[s], n);
    return readFirstInvocationARB(first) + before;
#endif
}
#endif

void main() {
    uint li = gl_LocalInvocationIndex;
    if (li < uint(RT_SLOTS)) group_count[li] = 0u;
    barrier();
    ivec3 p = classify_pixel(li);
    int slot = -1;
    if (all(lessThan(p.xy, textureSize(gb_material, 0).xy))) {
        uint effect = texelFetch(gb_material, p, 0).y;
        slot = effect < uint(MAX_EFFECT_ID) ? SLOT_OF_EFFECT[effect] : -1;
#ifdef STEREO_REUSE
        if (reuse_taken(p, textureSize(gb_material, 0).x)) slot = -1;  // takes the left eye's shading
#endif
        if (round_skips(p)) slot = -1;  // adds nothing to the frame (MSAA round): no effect traces it
    }
    uint local = 0u;
#if CLASSIFY_BALLOT != 0
    // Every lane takes part in every ballot (uniform control flow).
    for (int s = 0; s < RT_SLOTS; s++) {
        uint place = wave_place(uint(s), slot == s);
        if (slot == s) local = place;
    }
#else
    if (slot >= 0) local = atomicAdd(group_count[slot], 1u);
#endif
    barrier();
    if (li < uint(RT_SLOTS) && group_count[li] > 0u) group_base[li] = atomicAdd(rt_running[li], group_count[li]);
    memoryBarrierBuffer();
    barrier();
    if (slot >= 0) rt_pixels[uint(slot) * rt_capacity + group_base[slot] + local] = rt_pack_pixel(p);
    if (li == 0u) {
        // Every group's additions to rt_running precede its ticket; the last ticket sees them all.
        uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_NumWorkGroups.z;
        if (atomicAdd(rt_groups_done, 1u) == groups - 1u) {
            memoryBarrierBuffer();
            for (int s = 0; s < RT_SLOTS; s++) {
                uint n = atomicExchange(rt_running[s], 0u);
                uint wg = (n + uint(RT_LOCAL_SIZE) - 1u) / uint(RT_LOCAL_SIZE);
                uint gx = min(wg, RT_MAX_GROUPS_X);
                rt_args[s] = uvec4(gx, gx == 0u ? 1u : (wg + gx - 1u) / gx, 1u, n);
            }
            atomicExchange(rt_groups_done, 0u);
        }
    }
}
