// Which rays an invocation of a wavefront trace kernel (rt/wave_trace.comp) traces:
//   WAVE_FOR_EACH_RAY(k, n) { ... wave_ray(k) ... } runs its body for each k of [0, n) it takes.
// One ray per invocation (default): k is the invocation's index. WAVE_PERSISTENT (frame/passes/
// persistent_threads.py): a fixed number of work groups stay resident and each takes batches of
// RT_LOCAL_SIZE consecutive rays from an atomic counter of the kernel, one ray an invocation, the
// next batch as soon as its invocations are done with this one, until the batch's n rays are taken
// (Aila and Laine 2009, who fetch per warp; a work group is the unit GLSL can synchronise).
// WAVE_RAY_ORDER (frame/passes/ray_order.py): the k-th ray is the one of the k-th sorted
// (key, ray) pair, not ray k. Either way each ray's result goes to its own slot.
#ifndef RAYVR_RT_WAVE_FETCH_GLSL
#define RAYVR_RT_WAVE_FETCH_GLSL
#include "wave.glsl"

#if WAVE_RAY_ORDER
layout(std430, binding = SSBO_WAVE_ORDER) readonly restrict buffer WaveOrder { uvec2 wave_order[]; };
uint wave_ray(uint k) { return wave_order[k].y; }
#else
uint wave_ray(uint k) { return k; }
#endif

#if WAVE_PERSISTENT
shared uint wave_fetched;  // the first ray of the group's current batch
uint wave_fetch_batch() {  // in uniform control flow: every invocation of the group calls it
    barrier();  // the group is done with the last batch's first ray
    if (gl_LocalInvocationID.x == 0u)
        wave_fetched = atomicAdd(wave_fetch_counters[wave_fetch_slot], uint(RT_LOCAL_SIZE));
    barrier();
    return wave_fetched;
}
// The body runs for k = batch + local index while the group's batches start below n.
#define WAVE_FOR_EACH_RAY(k, n) \
    for (uint wave_batch = wave_fetch_batch(); wave_batch < (n); wave_batch = wave_fetch_batch()) \
        for (uint k = wave_batch + gl_LocalInvocationID.x; k < (n); k = (n))
#else
#define WAVE_FOR_EACH_RAY(k, n) for (uint k = wave_index(); k < (n); k = (n))
#endif

#endif
