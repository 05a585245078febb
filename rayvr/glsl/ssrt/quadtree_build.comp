#version 430
// Build one level of the screen-space quadtree (rayvr/frame/passes/quadtree.py runs one dispatch per
// level, leaves first; z = layer). Node format and the rules: rayvr/accel/quadtree.py, whose
// build_reference this mirrors.
//   level 0: each pixel's plane in S from the G-buffer: z0 = near / view depth (position.w), slopes
//            from the geometric normal of the pixel's triangle (gb_triangle, the scene's vertices):
//            the triangle's own plane, exactly (no finite differences; the shading normal, smoothed
//            across faces, tilted neighbouring planes of one face apart: docs/stereo.md); tree layers
//            past the eyes (qt_eyes) are the second depth layer's (frame/passes/second_layer.py:
//            layer2 = its triangle's geometric normal facing the eye, view depth);
//            background pixels are the AABB [0, 0]; the discontinuity flag from the 4 neighbours.
//   level k: from the (up to 2 x 2) children at level k - 1: a proxy plane when all are planes and
//            it passes gamma_norm / gamma_dist (gamma_dist = 0: never), else their AABB.
#ifndef QT_DEPTH_LAYERS
#define QT_DEPTH_LAYERS 1
#endif
#include "../layout.glsl"
layout(local_size_x = QT_BUILD_LOCAL, local_size_y = QT_BUILD_LOCAL) in;

#define QT_NODES_ACCESS
#include "quadtree.glsl"
#include "../common/gbuffer.glsl"
#include "../common/scene.glsl"

#if QT_DEPTH_LAYERS > 1
layout(binding = UNIT_LAYER2) uniform sampler2DArray layer2;  // xyz geometric normal facing the eye, w view depth
#endif

// QT_DISCONTINUITY, QT_GRAZING, QT_AABB_MARGIN: layout.glsl (rayvr/accel/quadtree.py)

uniform int qt_build_level;
uniform float gamma_norm;      // cosine: children's normals within this of the proxy's
uniform float gamma_dist;      // relative depth: children's corners within this of the proxy
uniform float gamma_adapt;     // §6 distance-adaptive: both thresholds x (1 + gamma_adapt x mean view depth)

vec2 pixels_per_tangent(int eye) {
    vec4 t = eye_tangents[eye];
    return vec2(qt_level[0].xy) / vec2(t.y - t.x, t.w - t.z);
}

vec2 tangent_at(int eye, vec2 p) {
    return eye_tangents[eye].xz + p / pixels_per_tangent(eye);
}

// The pixel's triangle's geometric normal (scene.glsl triangle_normal; zero for NO_HIT).
vec3 pixel_normal(uint tri) {
    return tri == NO_HIT ? vec3(0.0) : triangle_normal(scene_triangle(tri));
}

// The pixel's plane in tree layer p.z: false for background. z0 at the pixel centre, slopes
// relative to z0.
bool leaf_plane(ivec3 p, out float z0, out vec2 s) {
    z0 = 0.0; s = vec2(0.0);
    if (any(lessThan(p.xy, ivec2(0))) || any(greaterThanEqual(p.xy, qt_level[0].xy)))
        return false;
    int eye = p.z % qt_eyes;
    ivec3 e = ivec3(p.xy, eye);
#if QT_DEPTH_LAYERS > 1
    bool second = p.z >= qt_eyes;
    vec4 l2 = second ? texelFetch(layer2, e, 0) : vec4(0.0);
    float depth = second ? l2.w : texelFetch(gb_position, e, 0).w;
    vec3 nw = second ? l2.xyz : pixel_normal(texelFetch(gb_triangle, e, 0).x);
#else
    float depth = texelFetch(gb_position, e, 0).w;
    vec3 nw = pixel_normal(texelFetch(gb_triangle, e, 0).x);
#endif
    if (!(depth > 0.0))
        return false;
    vec3 nv = transpose(eye_rotation[eye]) * (nw * inversesqrt(max(dot(nw, nw), 1e-30)));
    vec2 t = tangent_at(eye, vec2(p.xy) + 0.5);
    // The slopes are the same for nv and -nv but for the grazing clamp, which wants nv facing the eye.
    float facing = dot(nv, vec3(t, -1.0));
    nv = facing > 0.0 ? -nv : nv;
    float den = min(-abs(facing), -QT_GRAZING * length(vec3(t, 1.0)));
    z0 = eye_depth.x / depth;
    s = nv.xy / den / pixels_per_tangent(eye);
    return true;
}

// View-space unit normal of the S-plane z = z0 (1 + s . (p - c)) (z0 > 0).
vec3 plane_normal(int eye, vec2 s, vec2 c) {
    vec2 a = s * pixels_per_tangent(eye);
    vec3 n = vec3(-a, 1.0 - dot(a, tangent_at(eye, c)));
    return n * inversesqrt(max(dot(n, n), 1e-30));
}

uvec2 build_leaf(ivec3 p) {
    float z0, zn;
    vec2 s, sn;
    bool geo = leaf_plane(p, z0, s);
    if (!geo)
        return qt_encode_aabb(0.0, 0.0, false);
    bool flag = false;
    for (int i = 0; i < 4; i++) {
        ivec2 o = ivec2(i == 0 ? 1 : i == 1 ? -1 : 0, i == 2 ? 1 : i == 3 ? -1 : 0);
        bool g = leaf_plane(p + ivec3(o, 0), zn, sn);
        bool inside = all(greaterThanEqual(p.xy + o, ivec2(0))) && all(lessThan(p.xy + o, qt_level[0].xy));
        if (!inside)
            continue;                   // the image border is no discontinuity
        vec2 e = 0.5 * vec2(o);        // shared edge midpoint, from each pixel's centre
        float za = z0 * (1.0 + dot(s, e));
        float zb = zn * (1.0 - dot(sn, e));
        flag = flag || !g || abs(za - zb) > QT_DISCONTINUITY * max(abs(za), abs(zb));
    }
    return qt_encode_plane(z0, s.x, s.y, flag);
}

uvec2 build_parent(int layer, int k, ivec2 q) {
    int eye = layer % qt_eyes;
    int kc = k - 1;
    vec4 rect = qt_rect(k, q);
    vec2 c = 0.5 * (rect.xy + rect.zw);
    bool flag = false, planes = true;
    float zmax = 0.0, zmin = QT_INF;
    QtNode ch[4];
    vec4 crect[4];
    bool exists[4];
    vec3 mean = vec3(0.0);
    float zsum = 0.0, count = 0.0;
    for (int i = 0; i < 4; i++) {
        ivec2 cq = 2 * q + ivec2(i & 1, i >> 1);
        exists[i] = all(lessThan(cq, qt_level[kc].xy));
        if (!exists[i])
            continue;
        ch[i] = qt_decode(qt_nodes[qt_index(layer, kc, cq)]);
        crect[i] = qt_rect(kc, cq);
        flag = flag || ch[i].flag;
        float hi = ch[i].zmax, lo = ch[i].zmin;
        if (ch[i].plane) {
            vec2 h = 0.5 * (crect[i].zw - crect[i].xy);
            float spread = abs(ch[i].sx) * h.x + abs(ch[i].sy) * h.y;
            hi = ch[i].z0 * (1.0 + spread);
            lo = max(ch[i].z0 * (1.0 - spread), 0.0);
            mean += plane_normal(eye, vec2(ch[i].sx, ch[i].sy), 0.5 * (crect[i].xy + crect[i].zw));
            zsum += ch[i].z0;
        }
        count += 1.0;
        planes = planes && ch[i].plane;
        zmax = max(zmax, hi);
        zmin = min(zmin, lo);
    }
    uvec2 aabb = qt_encode_aabb(zmin * (1.0 - QT_AABB_MARGIN), zmax * (1.0 + QT_AABB_MARGIN), flag);
    if (!(gamma_dist > 0.0) || !planes)
        return aabb;
    // Proxy normal: the children's mean; offset: least squares over their corners' z (z = kappa f).
    vec3 np = mean * inversesqrt(max(dot(mean, mean), 1e-30));
    float sfz = 0.0, sff = 0.0;
    for (int i = 0; i < 4; i++) {
        if (!exists[i])
            continue;
        vec2 cc = 0.5 * (crect[i].xy + crect[i].zw);
        for (int j = 0; j < 4; j++) {
            vec2 corner = vec2((j & 1) == 0 ? crect[i].x : crect[i].z, (j & 2) == 0 ? crect[i].y : crect[i].w);
            float zc = ch[i].z0 * (1.0 + ch[i].sx * (corner.x - cc.x) + ch[i].sy * (corner.y - cc.y));
            vec2 t = tangent_at(eye, corner);
            float f = -np.x * t.x - np.y * t.y + np.z;
            sfz += f * zc;
            sff += f * f;
        }
    }
    float kappa = sfz / sff;
    vec2 tc = tangent_at(eye, c);
    float pz0 = kappa * (-np.x * tc.x - np.y * tc.y + np.z);
    if (!(pz0 > 0.0) || isinf(pz0))
        return aabb;
    vec2 ps = kappa * -np.xy / pixels_per_tangent(eye) / pz0;
    uvec2 proxy = qt_encode_plane(pz0, ps.x, ps.y, flag);
    QtNode p = qt_decode(proxy);               // test what is stored
    vec3 pn = plane_normal(eye, vec2(p.sx, p.sy), c);
    float worst = 0.0, cosine = 1.0;
    for (int i = 0; i < 4; i++) {
        if (!exists[i])
            continue;
        vec2 cc = 0.5 * (crect[i].xy + crect[i].zw);
        cosine = min(cosine, dot(plane_normal(eye, vec2(ch[i].sx, ch[i].sy), cc), pn));
        for (int j = 0; j < 4; j++) {
            vec2 corner = vec2((j & 1) == 0 ? crect[i].x : crect[i].z, (j & 2) == 0 ? crect[i].y : crect[i].w);
            float zc = ch[i].z0 * (1.0 + ch[i].sx * (corner.x - cc.x) + ch[i].sy * (corner.y - cc.y));
            float zp = p.z0 * (1.0 + p.sx * (corner.x - c.x) + p.sy * (corner.y - c.y));
            if (!(zp > 0.0))
                return aabb;
            worst = max(worst, abs(zp - zc) / zp);
        }
    }
    // §6: coarser far away, where a depth error moves a hit by fewer pixels (rayvr/accel/quadtree.py
    // adaptive_thresholds).
    float f = 1.0 + gamma_adapt * eye_depth.x * count / zsum;  // mean z -> view depth near / z
    float gd = gamma_dist * f;
    float gn = gamma_adapt > 0.0 ? cos(min(acos(clamp(gamma_norm, -1.0, 1.0)) * f, 1.5707963)) : gamma_norm;
    return worst < gd && cosine >= gn ? proxy : aabb;
}

void main() {
    int layer = int(gl_GlobalInvocationID.z);  // tree layer: depth layer x qt_eyes + eye
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    int k = qt_build_level;
    if (any(greaterThanEqual(q, qt_level[k].xy)))
        return;
    qt_nodes[qt_index(layer, k, q)] = k == 0 ? build_leaf(ivec3(q, layer)) : build_parent(layer, k, q);
}
