// HMD lens pre-distortion (rayvr/frame/cameras/distorted.py): the panel point of a pixel, moved by the
// channel's radial polynomial around the eye's lens centre, or a measured sample table
// (camera_use_table: per channel, bilinear between the sample centres, missing samples skipped).
#include "../layout.glsl"

uniform vec3 camera_lens_k[3];       // (k1, k2, k3) per colour channel
uniform vec2 camera_lens_center[2];  // per eye, panel tangents
uniform int camera_use_table;
layout(binding = UNIT_CAMERA_SAMPLES) uniform sampler2DArray camera_sample_table;  // xyz eye-space direction, w valid

vec3 distorted_table(vec2 pixel, out bool valid) {
    ivec2 n = textureSize(camera_sample_table, 0).xy;
    vec2 f = pixel - 0.5, p0 = floor(f), a = f - p0;
    vec3 v = vec3(0.0);
    float total = 0.0;
    for (int k = 0; k < 4; k++) {
        ivec2 c = ivec2(k & 1, k >> 1);
        ivec2 q = clamp(ivec2(p0) + c, ivec2(0), n - 1);
        vec4 s = texelFetch(camera_sample_table, ivec3(q, camera_sample_channel()), 0);
        float w = (c.x == 1 ? a.x : 1.0 - a.x) * (c.y == 1 ? a.y : 1.0 - a.y) * s.w;
        v += w * s.xyz;
        total += w;
    }
    valid = total > 0.0;
    return v;
}

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    origin = eye_position[eye];
    bool valid = true;
    vec3 v;
    if (camera_use_table != 0) {
        v = distorted_table(pixel, valid);
    } else {
        vec4 t = eye_tangents[eye];
        vec2 q = mix(t.xz, t.yw, pixel / size) - camera_lens_center[eye];
        vec3 k = camera_lens_k[camera_sample_channel()];
        float r2 = dot(q, q);
        v = vec3(camera_lens_center[eye] + q * (1.0 + r2 * (k.x + r2 * (k.y + r2 * k.z))), -1.0);
    }
    direction = valid ? normalize(eye_rotation[eye] * v) : eye_forward(eye);
    return valid;
}

float camera_footprint(int eye, vec2 pixel, vec2 size) {
    if (camera_use_table == 0) return 1.0;
    return texelFetch(camera_sample_table, ivec3(ivec2(pixel), camera_sample_channel()), 0).w;
}
