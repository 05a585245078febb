// Wavefront state of the effect passes (rayvr/frame/passes/trace_effect.py TraceEffectPass): the shading
// kernels (rt/wave_shade.comp) write rays into these buffers, the lean trace kernels
// (rt/wave_trace.comp) trace them at the batch tracer's speed, and the shading kernels read back.
//
// Items: the pixels of a batch of the effect's pixel list, i in [0, n) with n = wave_args[0].w,
// and their paths p = j * n + i, j < wave_paths_per_pixel (glossy: one per GGX sample; otherwise
// one). A pixel's own shading event uses item i; the events along path p use item p.
// Shadow slot k of item q: wave_shadows[k * wave_slot_stride + q] (rays of neighbouring pixels for
// the same light sample lie side by side: coherent loads, coherent rays). The stride is the
// event's item capacity: the batch's pixels for a pixel event, its paths for a hit event, so a
// pixel event's many light samples (a set per path) take chunks `paths` times as large.
#ifndef RAYVR_RT_WAVE_GLSL
#define RAYVR_RT_WAVE_GLSL
#include "pixel_list.glsl"

#define WAVE_IDLE 0xFFFFFFFEu  // hit.x of a path with no ray this bounce

struct WavePath {
    vec4 origin;      // xyz ray origin (already offset off its surface), w tmin
    vec4 direction;   // xyz direction, w tmax; tmax < 0: the path has ended
    vec4 throughput;  // rgb weight of the radiance the ray brings back; w: shadow rays (uint bits)
    vec4 radiance;    // rgb gathered so far (the any-hit kernel adds the unoccluded lights)
    uvec4 hit;        // closest hit: BVH slot (BVH_MISS, WAVE_IDLE), triangle, u, v bits
};

struct ShadowSlot {
    vec4 origin;      // xyz, w tmin
    vec4 direction;   // xyz (to the light, unnormalized allowed), w tmax
    vec4 light;       // rgb contribution if unoccluded (path weight included), w the light's index
};

layout(std430, binding = SSBO_WAVE_PATHS) restrict buffer WavePaths { WavePath wave_paths[]; };
layout(std430, binding = SSBO_WAVE_SHADOWS) restrict buffer WaveShadows { ShadowSlot wave_shadows[]; };
// [0]: dispatch over the batch's pixels, [1]: over its paths; w = item count.
layout(std430, binding = SSBO_WAVE_ARGS) restrict buffer WaveArgs { uvec4 wave_args[2]; };
// The rays the trace kernels traced, [0] closest hits, [1] shadow rays, counted by the kernels
// compiled with WAVE_COUNT_RAYS 1 (frame/passes/trace_effect.py count_rays: zeroed and read back
// through GPU copies). Neither a uniform nor the indirect-dispatch buffer the CPU reads: on the NVIDIA GPU
// such counters lost the pixel events' counts after a renderer's first counting frame.
#ifndef WAVE_COUNT_RAYS
#define WAVE_COUNT_RAYS 0
#endif
#if WAVE_COUNT_RAYS
layout(std430, binding = SSBO_WAVE_RAYS) buffer WaveRays { uint wave_rays[2]; };
#define COUNT_RAYS(kind, n) if (n != 0u) atomicAdd(wave_rays[kind], n)
#else
#define COUNT_RAYS(kind, n)
#endif
#ifndef WAVE_PERSISTENT
#define WAVE_PERSISTENT 0
#endif
#ifndef WAVE_RAY_ORDER
#define WAVE_RAY_ORDER 0
#endif
#if WAVE_PERSISTENT
// One ray counter per trace kernel of a batch (rt/wave_fetch.glsl), zeroed by the prep kernel.
layout(std430, binding = SSBO_WAVE_FETCH) restrict buffer WaveFetch { uint wave_fetch_counters[]; };
uniform uint wave_fetch_slot;   // this trace kernel's counter
uniform uint wave_fetch_slots;  // the batch's trace kernels (prep zeroes their counters)
#endif

uniform uint wave_capacity;         // paths the buffers hold
uniform uint wave_slot_stride;      // items per row of the shadow slots (this event's capacity)
uniform uint wave_paths_per_pixel;  // paths per pixel (the effect's largest sample count)
uniform uint wave_slot_first;       // shadow rays [first, first + count) of each surface go to
uniform uint wave_slot_count;       //   slots 0.. of this chunk; the others are skipped
uniform uint wave_batch_base;       // first pixel-list entry of this batch

uint wave_index() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(RT_LOCAL_SIZE);
}

// Pixel (layer = eye) of batch pixel i.
ivec3 wave_pixel(uint i) {
    return rt_unpack_pixel(rt_pixels[uint(RT_SLOT) * rt_capacity + wave_batch_base + i]);
}

#endif
