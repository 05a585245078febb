// A workgroup reduction shared by the beam kernels (tile_cull.comp over a tile's rays, block_cull.comp
// over a block's tiles): REDUCE(x, op) leaves in red[0] the op (0 sum, 1 min, 2 max) over the group's
// REDUCE_GROUP invocations (a power of two) of each one's vec4 x; every invocation calls it, with its
// index `lid` in scope, and reads red[0] before the next barrier.
#ifndef RAYVR_ACCEL_GROUP_REDUCE_GLSL
#define RAYVR_ACCEL_GROUP_REDUCE_GLSL

shared vec4 red[REDUCE_GROUP];

#define REDUCE(x, op) { \
    red[lid] = (x); \
    barrier(); \
    for (uint st = uint(REDUCE_GROUP) / 2u; st > 0u; st >>= 1u) { \
        if (lid < st) \
            red[lid] = op == 0 ? red[lid] + red[lid + st] : (op == 1 ? min(red[lid], red[lid + st]) \
                                                                     : max(red[lid], red[lid + st])); \
        barrier(); \
    } \
}
#endif
