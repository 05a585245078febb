#version 430
// Stereo `reuse`, the map (rayvr/frame/passes/reuse.py): every left-eye hit is projected into the right
// eye; if the right eye sees it (the right eye's G-buffer pixel there shows the same surface: same
// material, within `reuse_tolerance` x depth of the hit's tangent plane, facing the right eye), it
// lands on that pixel. Of several landings on one pixel the one nearest its centre wins, then the
// lowest left pixel index: three kernels (REUSE_STAGE 0 clear, 1 nearest distance, 2 owner) make
// the choice deterministic with 32-bit atomics only.
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#ifndef REUSE_STAGE  // rayvr/frame/passes/reuse.py builds one program per stage
#define REUSE_STAGE 0
#endif
#define REUSE_ACCESS
#include "reuse.glsl"
#include "../common/gbuffer.glsl"
#include "../common/camera.glsl"

uniform float reuse_tolerance;  // tangent-plane distance allowed, relative to the right eye's view depth

// Where the hit of left-eye pixel `p` lands in the right eye (pinhole projection with the right
// eye's frustum tangents): pixel `r` and squared distance `d2` (pixels) from its centre; false
// when the right eye does not see it.
bool reuse_landing(ivec2 p, ivec2 size, out ivec2 r, out float d2) {
    r = ivec2(0); d2 = 0.0;
    Surface s = gbuffer_fetch(ivec3(p, 0));
    if (s.triangle == NO_HIT) return false;
    vec3 v = transpose(eye_rotation[1]) * (s.position - eye_position[1]);
    float depth = -v.z;
    if (!(depth > eye_depth.x)) return false;                     // at or before the right eye's near plane
    vec4 t = eye_tangents[1];
    vec2 f = (v.xy / depth - t.xz) / (t.yw - t.xz) * vec2(size);  // GL pixel coordinates
    if (any(lessThan(f, vec2(0.0))) || any(greaterThanEqual(f, vec2(size)))) return false;
    r = ivec2(f);
    vec2 off = f - (vec2(r) + 0.5);
    d2 = dot(off, off);
    if (dot(s.normal, eye_position[1] - s.position) <= 0.0) return false;  // faces away from the right eye
    Surface q = gbuffer_fetch(ivec3(r, 1));                                // what the right eye sees there
    if (q.triangle == NO_HIT || q.material != s.material) return false;
    return abs(dot(q.position - s.position, s.normal)) <= reuse_tolerance * depth;
}

void main() {
    ivec2 size = textureSize(gb_position, 0).xy;
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, size))) return;
    uint i = uint(p.x + p.y * size.x), n = uint(size.x * size.y);
#if REUSE_STAGE == 0
    reuse_map[i] = REUSE_NONE;
    reuse_map[n + i] = REUSE_NONE;
#else
    ivec2 r;
    float d2;
    if (!reuse_landing(p, size, r, d2)) return;
    uint ri = uint(r.x + r.y * size.x);
#if REUSE_STAGE == 1
    atomicMin(reuse_map[n + ri], floatBitsToUint(d2));  // d2 >= 0: its bits order as the floats do
#else
    if (reuse_map[n + ri] == floatBitsToUint(d2)) atomicMin(reuse_map[ri], i);
#endif
#endif
}
