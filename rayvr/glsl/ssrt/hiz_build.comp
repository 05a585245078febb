#version 430
// Build one level of the min-max depth pyramid of ssrt/hiz.glsl (rayvr/bench/tracers/hiz.py runs one
// dispatch per level, finest first; z = layer, so both eyes in one dispatch). rayvr/bench/tracers/hiz.py
// pyramid_reference is its numpy mirror.
//   level 0: each pixel's z = near / linear_depth as (zmin, zmax) = (z, z); background (depth 0,
//            or not a number) is (HIZ_EMPTY, 0), so it widens no cell and no ray passes below it.
//   level k: min and max over the (up to 2 x 2) cells of level k - 1; level k has ceil(W/2^k) x
//            ceil(H/2^k) cells, so an odd level's last row / column has one child per pair.
#include "../layout.glsl"
layout(local_size_x = HIZ_BUILD_LOCAL, local_size_y = HIZ_BUILD_LOCAL) in;

#define HIZ_LEVELS_ACCESS
#include "hiz.glsl"

layout(binding = GB_UNIT_LINEAR_DEPTH) uniform sampler2DArray hiz_linear_depth;
uniform int hiz_build_level;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    int k = hiz_build_level;
    if (any(greaterThanEqual(g.xy, hiz_level[k].xy)))
        return;
    vec2 mm = vec2(HIZ_EMPTY, 0.0);
    if (k == 0) {
        float depth = texelFetch(hiz_linear_depth, g, 0).x;
        if (depth > 0.0)
            mm = vec2(eye_depth.x / depth);
    } else {
        ivec2 below = hiz_level[k - 1].xy;
        for (int j = 0; j < 4; j++) {
            ivec2 c = 2 * g.xy + ivec2(j & 1, j >> 1);
            if (all(lessThan(c, below))) {
                vec2 v = hiz_cells[hiz_index(g.z, k - 1, c)];
                mm = vec2(min(mm.x, v.x), max(mm.y, v.y));
            }
        }
    }
    hiz_cells[hiz_index(g.z, k, g.xy)] = mm;
}
