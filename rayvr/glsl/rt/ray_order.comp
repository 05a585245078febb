#version 430
// The (key, ray) pairs the radix sort orders before a wavefront trace kernel (frame/passes/
// ray_order.py): entry i of [0, order_capacity) is ray i of the batch with its key
// (rt/ray_order.glsl), or ORDER_KEY_NONE where there is no ray to trace (sorted last, in index order).
//   ORDER_RAYS 1  the paths' rays (WAVE_STAGE 1 of rt/wave_trace.comp): an ended path has none
//   ORDER_RAYS 2  the items of a shadow kernel (WAVE_STAGE 2), each by its first shadow ray of
//                 the chunk (it traces all of them in one invocation); none where it has none
#ifndef RT_SLOT
#define RT_SLOT 0  // the pass passes its list (wave.glsl's wave_pixel, unused here)
#endif
#include "wave.glsl"
#include "ray_order.glsl"
layout(local_size_x = ORDER_GROUP) in;

layout(std430, binding = SSBO_WAVE_ORDER) writeonly restrict buffer OrderPairs { uvec2 order_pairs[]; };
uniform uint order_capacity;  // entries to write: the sort's count
uniform uint wave_items;      // ORDER_RAYS 2: 0 the batch's pixels, 1 its paths (wave_args index)

void main() {
    uint i = (gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x) * uint(ORDER_GROUP) + gl_LocalInvocationID.x;
    if (i >= order_capacity) return;
    uint key = ORDER_KEY_NONE;
#if ORDER_RAYS == 1
    if (i < wave_args[1].w && wave_paths[i].direction.w >= 0.0)
        key = ray_order_key(wave_paths[i].origin.xyz, wave_paths[i].direction.xyz);
#else
    if (i < wave_args[wave_items].w && floatBitsToUint(wave_paths[i].throughput.w) > 0u)
        key = ray_order_key(wave_shadows[i].origin.xyz, wave_shadows[i].direction.xyz);
#endif
    order_pairs[i] = uvec2(key, i);
}
