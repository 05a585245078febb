#version 430
// Copies one texel of the G-buffer's material channel (material index, effect ID) into a
// tiny buffer, so the HUD can name what is under the cursor without reading the whole channel.
layout(local_size_x = 1) in;
#include "../layout.glsl"

layout(binding = GB_UNIT_MATERIAL) uniform usampler2DArray gb_material;
layout(std430, binding = SSBO_PICKED) writeonly buffer Picked { uvec2 picked; };
uniform ivec3 texel;  // x, y (GL bottom-up rows), layer

void main() {
    picked = texelFetch(gb_material, texel, 0).xy;
}
