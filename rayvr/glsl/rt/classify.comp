#version 430
// Classify: append each pixel whose effect is ray traced to that effect's list (rt/pixel_list.glsl).
// Work-group aggregation: one shared-memory atomic per pixel, one global atomic per group and list,
// so an 8x8 tile of one effect lands as 64 consecutive entries (coherent rays in the effect pass).
// With FINALIZE defined: turn the counts into indirect dispatch sizes (one invocation per list).
// (The include preprocessor takes each file once per program, so includes sit outside the #if.)
#include "pixel_list.glsl"
#include "../common/gbuffer.glsl"
#ifdef FINALIZE
layout(local_size_x = RT_SLOTS) in;
void main() {
    uint s = gl_LocalInvocationID.x;
    uint groups = (rt_args[s].w + uint(RT_LOCAL_SIZE) - 1u) / uint(RT_LOCAL_SIZE);
    uint gx = min(groups, RT_MAX_GROUPS_X);
    uint gy = gx == 0u ? 1u : (groups + gx - 1u) / gx;
    rt_args[s].xyz = uvec3(gx, gy, 1u);
}
#else
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

const int SLOT_OF_EFFECT[8] = RT_SLOT_TABLE;  // effect ID -> list slot, -1: not traced
shared uint group_count[RT_SLOTS];
shared uint group_base[RT_SLOTS];

void main() {
    uint li = gl_LocalInvocationIndex;
    if (li < uint(RT_SLOTS)) group_count[li] = 0u;
    barrier();
    ivec3 p = ivec3(gl_GlobalInvocationID);
    int slot = -1;
    if (all(lessThan(p.xy, textureSize(gb_material, 0).xy))) {
        uint effect = texelFetch(gb_material, p, 0).y;
        slot = effect < 8u ? SLOT_OF_EFFECT[effect] : -1;
    }
    uint local = 0u;
    if (slot >= 0) local = atomicAdd(group_count[slot], 1u);
    barrier();
    if (li < uint(RT_SLOTS) && group_count[li] > 0u) group_base[li] = atomicAdd(rt_args[li].w, group_count[li]);
    barrier();
    if (slot >= 0) rt_pixels[uint(slot) * rt_capacity + group_base[slot] + local] = rt_pack_pixel(p);
}
#endif
