#version 430
// Tonemap: exposure, tonemapper (common/color.glsl), sRGB encoding into 8-bit output.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/color.glsl"

#ifndef HDR_FORMAT
#define HDR_FORMAT rgba16f  // rgba32f when it shows the accumulated or denoised colour
#endif
layout(HDR_FORMAT, binding = IMAGE_HDR) uniform readonly image2DArray hdr_in;
layout(rgba8, binding = IMAGE_LDR) uniform writeonly image2DArray ldr_out;
uniform float exposure;
uniform int tonemapper;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p.xy, imageSize(ldr_out).xy))) return;
    vec3 c = imageLoad(hdr_in, p).rgb * exposure;
    imageStore(ldr_out, p, vec4(linear_to_srgb(tonemap(c, tonemapper)), 1.0));
}
