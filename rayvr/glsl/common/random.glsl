// Per-pixel random numbers for sampling (area lights, GGX lobes): a PCG hash stream, seeded from
// pixel, eye and frame, so a frame is deterministic and neighbouring pixels decorrelate.
#ifndef RAYVR_RANDOM_GLSL
#define RAYVR_RANDOM_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

uint rng_seed(ivec3 pixel, uint frame) {
    return pcg_hash(uint(pixel.x) ^ pcg_hash(uint(pixel.y) ^ pcg_hash(uint(pixel.z) ^ pcg_hash(frame))));
}

// Uniform in [0, 1): the top 24 bits, so 1.0 is never returned.
float rng_next(inout uint state) {
    state = pcg_hash(state);
    return float(state >> 8) * (1.0 / 16777216.0);
}

vec2 rng_next2(inout uint state) {
    return vec2(rng_next(state), rng_next(state));
}

#endif
