// Per-eye camera data and primary-ray generation, shared by every pass that needs the camera's
// rays (G-buffer resolve, ray-traced primary visibility, shading). The rays come from the camera
// model chosen by the CAMERA_MODEL define (a rayvr/cameras model's `defines()`; default the
// pinhole), whose file under glsl/cameras/ implements the two functions declared below
// (contract in rayvr/cameras/base.py). Uniform values: rayvr/cameras/base.py uniforms().
#ifndef RAYVR_CAMERA_GLSL
#define RAYVR_CAMERA_GLSL

uniform vec3 eye_position[2];  // scene-local (world - scene origin)
uniform mat3 eye_rotation[2];  // camera-to-world; columns right, up, back
uniform vec4 eye_tangents[2];  // frustum tangents: left, right, bottom, top
uniform vec2 eye_depth;        // near, far (0: infinite far plane)

// One value per model (CameraModel.glsl_define).
#define CAMERA_PINHOLE 1
#ifndef CAMERA_MODEL
#define CAMERA_MODEL CAMERA_PINHOLE
#endif
#if CAMERA_MODEL != CAMERA_PINHOLE
#error unknown CAMERA_MODEL: the allowed values are listed in rayvr/cameras CAMERA_MODELS
#endif

// The camera ray through `pixel` (GL image coordinates: x right, y up, centres at +0.5) of an
// image of `size` pixels: scene-local origin, unit direction; false where the sample makes no ray.
bool camera_ray(int eye, vec2 pixel, vec2 size, out vec3 origin, out vec3 direction);
// The directions of the rays one pixel right (+x) and one pixel up (+y) of `pixel`, from the same
// origin: the footprint that texture LOD needs (Mitsuba's ray differentials d_x, d_y).
void camera_ray_neighbours(int eye, vec2 pixel, vec2 size, out vec3 direction_x, out vec3 direction_y);

// Kept for shaders written before camera models: new code calls camera_ray(), which also gives
// the origin and whether the sample makes a ray at all.
vec3 eye_ray_direction(int eye, vec2 pixel, vec2 size) {
    vec3 origin, direction;
    camera_ray(eye, pixel, size, origin, direction);
    return direction;
}

vec3 eye_forward(int eye) { return -eye_rotation[eye][2]; }

// Reversed-Z depth value -> linear view depth (see rayvr/camera.py projection()).
float eye_view_depth(float z) {
    float n = eye_depth.x, f = eye_depth.y;
    return f == 0.0 ? n / z : n * f / (z * (f - n) + n);
}

// The chosen model's code, last: the model files skipped by the #if still count lines, which
// would shift the line numbers of anything after them in this file in compile errors.
#if CAMERA_MODEL == CAMERA_PINHOLE
#include "../cameras/pinhole.glsl"
#endif

#endif
