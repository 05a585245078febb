// Perspective-correct DDA screen-space ray marching (McGuire & Mara 2014), the baseline of the
// screen-space tracers. rayvr/bench/tracers/dda.py (trace_dda) is its numpy mirror, step for step, and its
// docstring describes the march; tests/test_dda.py compares the two.
//
//   DdaResult dda_trace(int eye, vec3 origin, vec3 direction, vec2 size,
//                       int max_steps, float stride, float thickness_factor);
//
//   eye          layer of the G-buffer (and index of the camera uniforms) the ray is traced in
//   origin       scene-local ray origin (world - scene origin), as G-buffer positions are
//   direction    ray direction, scene-local (need not be unit length; not zero)
//   size         the layer's size in pixels
//   max_steps    most pixels tested; running out is DDA_NONE
//   stride       pixels per step along the major screen axis (>= 1; 1 tests every column)
//   thickness_factor  1 / (1 + thickness): each pixel is a slab from its view depth d to
//                d * (1 + thickness) (a thickness relative to depth: the same test at every
//                scale); 0 = infinite thickness, a solid height field
//
// Screen space S of a layer: x, y in pixels (GL: origin bottom-left, centres at +0.5), z = near /
// view_depth (1 at the near plane, 0 at infinity). Rays are straight lines in S and z is linear
// along them. The result: status DDA_HIT / DDA_OFFSCREEN (left the viewport) / DDA_NEAR (reached
// the near plane, or lies wholly in front of it) / DDA_NONE (max_steps without a hit, or reached
// infinity on screen); `pixel` and `point` (in S) of the hit, else of the last pixel tested
// (pixel (-1, -1) and point = the origin in S when none was); `steps` = pixels tested. The
// column (row) of the origin's pixel is not tested: the origin is taken to lie on the surface
// that pixel shows (a reflection ray); a ray straight into the screen therefore tests nothing.
//
// Reads: the camera uniforms of common/camera.glsl (eye_position, eye_rotation, eye_tangents,
// eye_depth.x = near) and the pixels' view depth through DDA_DEPTH(ivec3(x, y, eye)), by default
// the G-buffer's linear_depth channel (0 = background) at texture unit GB_UNIT_LINEAR_DEPTH
// (rayvr/frame/gbuffer.py GBuffer.bind_for_reading binds it). Define DDA_DEPTH before including this
// file to read depth from elsewhere.
#ifndef RAYVR_SSRT_DDA_GLSL
#define RAYVR_SSRT_DDA_GLSL
#include "../layout.glsl"
#include "../common/camera.glsl"

#ifndef DDA_DEPTH
layout(binding = GB_UNIT_LINEAR_DEPTH) uniform sampler2DArray dda_linear_depth;
#define DDA_DEPTH(p) texelFetch(dda_linear_depth, p, 0).x
#endif

// Ties: a ray leaving through the side it marches towards ends exactly on a column boundary,
// and rays from pixel centres with simple slopes meet pixel edges exactly at column centres. So
// rounding (which differs between drivers) decides nothing, a column is tested only if the
// segment reaches DDA_EDGE px into it, and the pixel is picked DDA_BIAS px further along the ray.
// (DDA_EDGE, DDA_BIAS: layout.glsl, from rayvr/bench/tracers/dda.py)

#define DDA_HIT SSRT_HIT
#define DDA_OFFSCREEN SSRT_OFFSCREEN
#define DDA_NEAR SSRT_NEAR
#define DDA_NONE SSRT_NONE

struct DdaResult {
    uint status;
    ivec2 pixel;
    vec3 point;
    uint steps;
};

DdaResult dda_trace(int eye, vec3 origin, vec3 direction, vec2 size, int max_steps, float stride,
                    float thickness_factor) {
    DdaResult res = DdaResult(0u, ivec2(-1), vec3(0.0), 0u);
    float near = eye_depth.x;
    vec4 tg = eye_tangents[eye];
    vec2 scale = size / vec2(tg.y - tg.x, tg.w - tg.z);

    // 1. view space; w = view depth
    vec3 v0 = (origin - eye_position[eye]) * eye_rotation[eye];
    vec3 dv = direction * eye_rotation[eye];
    float w0 = -v0.z, dw = -dv.z;
    // an origin in front of the near plane moves along the ray onto it (McGuire's near clip);
    // a ray that does not go away from the eye from there never enters the frustum
    bool clipped = !(w0 >= near);
    bool behind = clipped && !(dw > 0.0);
    if (clipped) {
        v0 += (behind ? 0.0 : (near - w0) / dw) * dv;
        w0 = near;
    }

    // 2. the line S(u) = s0 + u D, u = t / w(t); where it ends
    vec3 s0 = vec3((v0.x / w0 - tg.x) * scale.x, (v0.y / w0 - tg.z) * scale.y, near / w0);
    vec2 hd = vec2((dv.x - tg.x * dw) * scale.x, (dv.y - tg.z * dw) * scale.y);
    vec3 D = vec3(hd.x - s0.x * dw, hd.y - s0.y * dw, -s0.z * dw);
    res.point = s0;
    if (behind) {
        res.status = DDA_NEAR;
        return res;
    }
    float INF = uintBitsToFloat(0x7F800000u);
    float u_hi = dw > 0.0 ? 1.0 / dw : (dw < 0.0 ? (w0 - near) / (-dw * near) : INF);
    uint end_status = dw < 0.0 ? DDA_NEAR : DDA_NONE;

    // 3. clip to the viewport [0, W] x [0, H]
    float u_lo = 0.0;
    bool outside = false;
    for (int k = 0; k < 2; k++) {
        if (D[k] != 0.0) {
            float ua = (0.0 - s0[k]) / D[k];
            float ub = (size[k] - s0[k]) / D[k];
            u_lo = max(u_lo, min(ua, ub));
            float screen_hi = max(ua, ub);
            if (screen_hi < u_hi)
                end_status = DDA_OFFSCREEN;
            u_hi = min(u_hi, screen_hi);
        } else if (s0[k] < 0.0 || s0[k] > size[k]) {
            outside = true;
        }
    }
    if (outside || !(u_lo < u_hi)) {
        res.status = DDA_OFFSCREEN;
        return res;
    }

    // 4. unit steps along the major axis; sample k at the column centre c_k
    float m = max(abs(D.x), abs(D.y));
    bool degenerate = !(m > 0.0);
    vec3 Dn = D / (degenerate ? 1.0 : m);
    int major = abs(D.x) >= abs(D.y) ? 0 : 1;
    // the clipped segment spans at most the image along the major axis (a guard against overflow)
    float a_hi = degenerate ? 0.0 : min((u_hi - u_lo) * m, size[major]);
    vec3 s_lo = s0 + u_lo * D;
    float x_lo = s_lo[major];
    float sgn = Dn[major] < 0.0 ? -1.0 : 1.0;
    float col0 = sgn > 0.0 ? floor(x_lo) : ceil(x_lo) - 1.0;
    float k = u_lo > 0.0 || clipped ? 0.0 : 1.0;  // skip the origin's column, unless moved
    float half_stride = stride * 0.5;
    ivec2 last = ivec2(size) - 1;

    for (;;) {
        if (res.steps >= uint(max_steps)) {
            res.status = DDA_NONE;
            return res;
        }
        float c = col0 + 0.5 + sgn * k * stride;
        float ak = (c - x_lo) * sgn;
        float a_start = max(ak - half_stride, 0.0);
        if (!(a_start + DDA_EDGE < a_hi)) {
            res.status = end_status;
            return res;
        }
        float a_end = min(ak + half_stride, a_hi);
        float ap = min(ak, a_hi);
        vec2 p = s_lo.xy + ap * Dn.xy + DDA_BIAS * sign(Dn.xy);
        ivec2 px = clamp(ivec2(floor(p)), ivec2(0), last);
        res.pixel = px;
        res.point = s_lo + ap * Dn;
        res.steps += 1u;
        k += 1.0;
        float za = s_lo.z + a_start * Dn.z;
        float zb = s_lo.z + a_end * Dn.z;
        float ld = DDA_DEPTH(ivec3(px, eye));
        float zs = near / (ld > 0.0 ? ld : 1.0);
        if (ld > 0.0 && min(za, zb) <= zs && max(za, zb) >= zs * thickness_factor) {
            float across = Dn.z != 0.0 ? (zs - s_lo.z) / Dn.z : a_start;
            res.point = s_lo + clamp(across, a_start, a_end) * Dn;
            res.status = DDA_HIT;
            return res;
        }
    }
    return res;
}

#endif
