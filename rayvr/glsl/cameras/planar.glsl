// The planar frustum of the eye's tangents (rayvr/frame/cameras/pinhole.py planar_directions): shared
// by the models whose samples lie on it (pinhole, foveated, thin lens).
#ifndef RAYVR_PLANAR_GLSL
#define RAYVR_PLANAR_GLSL
vec3 pinhole_direction(int eye, vec2 pixel, vec2 size) {
    vec4 t = eye_tangents[eye];
    vec2 f = pixel / size;
    vec3 d = vec3(mix(t.x, t.y, f.x), mix(t.z, t.w, f.y), -1.0);
    return normalize(eye_rotation[eye] * d);
}
#endif
