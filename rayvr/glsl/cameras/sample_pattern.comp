#version 430
// The `samples` view (frame/passes/sample_pattern.py): where the camera model samples. Each pixel with
// a sample is grey by its density (1 / footprint^2: foveated patterns fade outwards), black
// without one; white lines are every 10 degrees of yaw and pitch of its ray (eye space), so a
// lens pre-distortion bends them, a wide mapping spreads them; each colour channel set is drawn
// into its own channel (chromatic pre-correction shows as coloured fringes).
#include "../layout.glsl"  // PIXEL_TILE: rayvr/frame/passes/compute.py TILE
layout(local_size_x = PIXEL_TILE, local_size_y = PIXEL_TILE, local_size_z = 1) in;
#include "../common/camera.glsl"

layout(rgba8, binding = IMAGE_LDR) uniform image2DArray ldr_out;
uniform int channel_out;  // -1: all of rgb; else this channel (one dispatch per channel set)

vec2 angles_deg(int eye, vec3 d) {
    vec3 e = transpose(eye_rotation[eye]) * d;
    return degrees(vec2(atan(e.x, -e.z), asin(clamp(e.y, -1.0, 1.0))));
}

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 n = imageSize(ldr_out).xy;
    if (any(greaterThanEqual(p.xy, n))) return;
    vec2 size = vec2(n), pixel = vec2(p.xy) + 0.5;
    float f = camera_footprint(p.z, pixel, size);
    vec3 o, d, dx, dy;
    bool valid = camera_ray_at(p.z, pixel, size, vec2(0.0), o, d) && f > 0.0;
    camera_ray_at(p.z, pixel + vec2(1.0, 0.0), size, vec2(0.0), o, dx);
    camera_ray_at(p.z, pixel + vec2(0.0, 1.0), size, vec2(0.0), o, dy);
    vec2 a = floor(angles_deg(p.z, d) / 10.0);
    bool line = any(notEqual(a, floor(angles_deg(p.z, dx) / 10.0))) || any(notEqual(a, floor(angles_deg(p.z, dy) / 10.0)));
    float v = valid ? (line ? 1.0 : 0.15 + 0.45 / (f * f)) : 0.0;
    vec4 c = channel_out < 0 ? vec4(v) : imageLoad(ldr_out, p);
    if (channel_out >= 0) c[channel_out] = v;
    imageStore(ldr_out, p, vec4(c.rgb, 1.0));
}
