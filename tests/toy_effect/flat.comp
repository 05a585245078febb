#version 430
// The toy effect of tests/test_effect_plugin.py: its pixels (from the classify pass's list) get
// `glow` x `gain` x their base colour (`gain`: a frame parameter, one uniform for the frame). Built
// from outside rayvr/glsl: the includes come from rayvr's.
layout(local_size_x = 64) in;
#include "rt/pixel_list.glsl"
#include "common/gbuffer.glsl"
#include "common/scene.glsl"

layout(rgba16f, binding = IMAGE_HDR) uniform writeonly image2DArray hdr_out;
uniform float param_gain;

void main() {
    ivec3 px;
    if (!rt_list_item(uint(RT_SLOT), px)) return;
    Surface s = gbuffer_fetch(px);
    imageStore(hdr_out, px, vec4(material_param_float(s.material, PARAM_GLOW) * param_gain * s.base_color, 1.0));
}
