// Random numbers for sampling (area lights, GGX lobes): a PCG hash stream, seeded per surface point
// and frame, so a frame is deterministic, neighbouring pixels decorrelate and both eyes agree.
#ifndef RAYVR_RANDOM_GLSL
#define RAYVR_RANDOM_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Seeded from the surface point, not the pixel: both eyes draw the same samples for the same
// point (noise that differs between the eyes shimmers in a headset; with IPD 0 the eyes are
// identical). The point is quantized to cells of 1/2..1 of the pixel footprint there, a power of
// two so that both eyes pick the same cell size for the same point.
uint rng_seed_surface(vec3 p, float footprint, uint frame) {
    int level = int(floor(log2(max(footprint, 1e-30))));
    ivec3 cell = ivec3(clamp(floor(p * exp2(float(-level))), vec3(-2.0e9), vec3(2.0e9)));
    return pcg_hash(uint(cell.x) ^ pcg_hash(uint(cell.y) ^ pcg_hash(uint(cell.z) ^
                    pcg_hash(uint(level) ^ pcg_hash(frame)))));
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
