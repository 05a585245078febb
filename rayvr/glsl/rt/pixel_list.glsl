// Per-effect pixel lists: the classify pass (rt/classify.comp) appends every pixel whose material
// asks for a ray-traced effect to that effect's list; each effect pass then runs with an indirect
// dispatch over its list only, both eyes at once. Layout mirrors rayvr/frame/passes/classify.py.
#ifndef RAYVR_RT_PIXEL_LIST_GLSL
#define RAYVR_RT_PIXEL_LIST_GLSL
#include "../layout.glsl"  // RT_SLOTS, RT_SLOT_TABLE: one list per traced effect of the registry;
                           // RT_LOCAL_SIZE: rayvr/frame/passes/classify.py
#define RT_MAX_GROUPS_X 65535u    // GL's minimum max work group count per dimension

// Per list: dispatch size (x, y, z) for glDispatchComputeIndirect, then the pixel count. After
// them the classify pass's running counts and finished-group ticket (zero between frames).
layout(std430, binding = SSBO_RT_LIST_ARGS) restrict buffer RtListArgs {
    uvec4 rt_args[RT_SLOTS];
    uint rt_running[RT_SLOTS];
    uint rt_groups_done;
};
// List `slot` occupies [slot * rt_capacity, slot * rt_capacity + count).
layout(std430, binding = SSBO_RT_LISTS) restrict buffer RtLists { uint rt_pixels[]; };
uniform uint rt_capacity;

// x and y up to 16383 (14 bits each), layer (eye) in the top bits.
uint rt_pack_pixel(ivec3 p) { return uint(p.x) | (uint(p.y) << 14) | (uint(p.z) << 28); }
ivec3 rt_unpack_pixel(uint v) { return ivec3(int(v & 0x3FFFu), int((v >> 14) & 0x3FFFu), int(v >> 28)); }

// Index into list `slot` of this invocation of an indirect dispatch; false past the end.
bool rt_list_item(uint slot, out ivec3 pixel) {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * RT_LOCAL_SIZE;
    if (i >= rt_args[slot].w) return false;
    pixel = rt_unpack_pixel(rt_pixels[slot * rt_capacity + i]);
    return true;
}

#endif
