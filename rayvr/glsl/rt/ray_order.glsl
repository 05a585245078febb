// The sort key of a wavefront ray (frame/passes/ray_order.py, which has the same in numpy): its
// direction's octant in the 3 high bits (x < 0, y < 0, z < 0), under them the Morton code of its
// origin's cell, the scene's bounds cut into 2^ORDER_AXIS_BITS cells an axis (x's bit highest).
#ifndef RAYVR_RT_RAY_ORDER_GLSL
#define RAYVR_RT_RAY_ORDER_GLSL
#include "../layout.glsl"  // ORDER_AXIS_BITS: rayvr/frame/passes/ray_order.py

uniform vec3 order_lo;     // scene-local bounds' low corner
uniform vec3 order_scale;  // cells per unit along each axis

uint order_spread(uint c) {  // c's ORDER_AXIS_BITS low bits, two zero bits after each
    uint out_bits = 0u;
    for (int b = 0; b < ORDER_AXIS_BITS; ++b) out_bits |= ((c >> uint(b)) & 1u) << uint(3 * b);
    return out_bits;
}

uint ray_order_key(vec3 origin, vec3 direction) {
    vec3 at = clamp((origin - order_lo) * order_scale, vec3(0.0), vec3(float((1 << ORDER_AXIS_BITS) - 1)));
    uvec3 cell = uvec3(at);
    uint morton = (order_spread(cell.x) << 2u) | (order_spread(cell.y) << 1u) | order_spread(cell.z);
    uint octant = (direction.x < 0.0 ? 4u : 0u) | (direction.y < 0.0 ? 2u : 0u) | (direction.z < 0.0 ? 1u : 0u);
    return (octant << uint(3 * ORDER_AXIS_BITS)) | morton;
}

#endif
