#version 430
// Depth peeling (frame/passes/second_layer.py, peel): the visibility raster again, keeping only
// fragments strictly behind the G-buffer's surface in this pixel and not of its triangle; the
// depth test then leaves the nearest of them: the second depth layer's triangle ID.
#include "../layout.glsl"
layout(location = 0) out uint out_triangle;
layout(binding = GB_UNIT_DEPTH) uniform sampler2DArray gb_depth;         // reversed-Z: larger is nearer
layout(binding = GB_UNIT_TRIANGLE) uniform usampler2DArray gb_triangle;

void main() {
    ivec3 p = ivec3(ivec2(gl_FragCoord.xy), gl_Layer);
    if (uint(gl_PrimitiveID) == texelFetch(gb_triangle, p, 0).x || gl_FragCoord.z >= texelFetch(gb_depth, p, 0).x)
        discard;
    out_triangle = uint(gl_PrimitiveID);
}
