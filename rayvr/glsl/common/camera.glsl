// Per-eye camera data and primary-ray generation, shared by every pass that needs the rays the
// rasterizer used (G-buffer resolve, ray-traced primary visibility, shading). Mirrors
// rayvr/camera.py EyeView.ray_directions: pixel centres, frustum tangents, camera-to-world.
#ifndef RAYVR_CAMERA_GLSL
#define RAYVR_CAMERA_GLSL

uniform vec3 eye_position[2];  // scene-local (world - scene origin)
uniform mat3 eye_rotation[2];  // camera-to-world; columns right, up, back
uniform vec4 eye_tangents[2];  // frustum tangents: left, right, bottom, top
uniform vec2 eye_depth;        // near, far (0: infinite far plane)

// `pixel` in GL image coordinates (x right, y up; centres at +0.5), `size` the image size.
vec3 eye_ray_direction(int eye, vec2 pixel, vec2 size) {
    vec4 t = eye_tangents[eye];
    vec2 f = pixel / size;
    vec3 d = vec3(mix(t.x, t.y, f.x), mix(t.z, t.w, f.y), -1.0);
    return normalize(eye_rotation[eye] * d);
}

vec3 eye_forward(int eye) { return -eye_rotation[eye][2]; }

// Reversed-Z depth value -> linear view depth (see rayvr/camera.py projection()).
float eye_view_depth(float z) {
    float n = eye_depth.x, f = eye_depth.y;
    return f == 0.0 ? n / z : n * f / (z * (f - n) + n);
}

#endif
