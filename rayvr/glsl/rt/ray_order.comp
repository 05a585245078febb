#version 430
// The (key, ray) pairs the radix sort orders before a wavefront trace kernel (frame/passes/
// ray_order.py): entry i of the n rays (or items) of the batch, n = wave_args[slot].w, is i with its
// key (rt/ray_order.glsl), or ORDER_KEY_NONE where there is nothing to trace (sorted last, in index
// order); the sort counts the same n (SORT_COUNTED), the entries past it are left as they are.
//   ORDER_RAYS 1  the paths' rays (WAVE_STAGE 1 of rt/wave_trace.comp, slot 1): an ended path has none
//   ORDER_RAYS 2  the items of a shadow kernel (WAVE_STAGE 2, slot wave_items), each by its first
//                 shadow ray of the chunk (it traces all of them in one invocation); none where it has none
#ifndef RT_SLOT
#define RT_SLOT 0  // the pass passes its list (wave.glsl's wave_pixel, unused here)
#endif
#include "wave.glsl"
#include "ray_order.glsl"
layout(local_size_x = ORDER_GROUP) in;

layout(std430, binding = SSBO_WAVE_ORDER) writeonly restrict buffer OrderPairs { uvec2 order_pairs[]; };
uniform uint order_capacity;  // entries the buffer holds (the dispatch's size)
uniform uint wave_items;      // ORDER_RAYS 2: 0 the batch's pixels, 1 its paths (wave_args index)

void main() {
    uint i = (gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x) * uint(ORDER_GROUP) + gl_LocalInvocationID.x;
#if ORDER_RAYS == 1
    if (i >= min(order_capacity, wave_args[1].w)) return;
    uint key = wave_paths[i].direction.w >= 0.0
        ? ray_order_key(wave_paths[i].origin.xyz, wave_paths[i].direction.xyz) : ORDER_KEY_NONE;
#else
    if (i >= min(order_capacity, wave_args[wave_items].w)) return;
    uint key = floatBitsToUint(wave_paths[i].throughput.w) > 0u
        ? ray_order_key(wave_shadows[i].origin.xyz, wave_shadows[i].direction.xyz) : ORDER_KEY_NONE;
#endif
    order_pairs[i] = uvec2(key, i);
}
