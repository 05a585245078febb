#version 430
// Stereo `reuse`, the copy (rayvr/frame/passes/reuse.py): each right-eye pixel of the map takes the
// finished HDR colour of its left-eye pixel (after every effect composed its pixels).
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "reuse.glsl"

layout(rgba16f, binding = IMAGE_HDR) uniform restrict image2DArray hdr_image;

void main() {
    ivec2 size = imageSize(hdr_image).xy;
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, size))) return;
    uint src = reuse_map[uint(p.x + p.y * size.x)];
    if (src == REUSE_NONE) return;
    ivec2 l = ivec2(int(src % uint(size.x)), int(src / uint(size.x)));
    imageStore(hdr_image, ivec3(p, 1), imageLoad(hdr_image, ivec3(l, 0)));
}
