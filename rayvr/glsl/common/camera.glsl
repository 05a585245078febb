// Per-eye camera data and primary-ray generation, shared by every pass that needs the camera's
// rays (ray-traced primary visibility, G-buffer resolve, shading). The rays come from the camera
// model chosen by the CAMERA_MODEL define (a rayvr/frame/cameras model's `defines()`; default the
// pinhole), whose file under glsl/cameras/ implements camera_ray_at and camera_footprint
// (contract in rayvr/frame/cameras/base.py). Uniform values: rayvr/frame/cameras/base.py uniforms().
#ifndef RAYVR_CAMERA_GLSL
#define RAYVR_CAMERA_GLSL

uniform vec3 eye_position[2];  // scene-local (world - scene origin)
uniform mat3 eye_rotation[2];  // camera-to-world; columns right, up, back
uniform vec4 eye_tangents[2];  // frustum tangents: left, right, bottom, top
uniform vec2 eye_depth;        // near, far (0: infinite far plane)
uniform int camera_channel;    // the colour channel set this frame round samples (CameraModel.channels)

// One value per model, CAMERA_<NAME> = 1 .. CAMERA_MODEL_COUNT (CameraModel.glsl_define; layout.glsl,
// from rayvr/frame/cameras CAMERA_MODELS).
#include "../layout.glsl"
#ifndef CAMERA_MODEL
#define CAMERA_MODEL CAMERA_PINHOLE
#endif
#if CAMERA_MODEL < 1 || CAMERA_MODEL > CAMERA_MODEL_COUNT
#error unknown CAMERA_MODEL: the allowed values are listed in rayvr/frame/cameras CAMERA_MODELS
#endif
#include "../cameras/sampling.glsl"

// The model's contract (rayvr/frame/cameras/base.py): the ray through continuous image position
// `pixel` (GL: x right, y up, centres at +0.5) and unit-disk lens point `lens`, and the footprint
// of the sample at a pixel centre (0: no sample there).
bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction);
float camera_footprint(int eye, vec2 pixel, vec2 size);

// Sub-ray i of CAMERA_SUBSAMPLES of the sample at pixel centre `pixel` (cameras/sampling.glsl):
// scene-local origin, unit direction; false where the sample makes no ray.
bool camera_subray(int eye, vec2 pixel, vec2 size, uint i, out vec3 origin, out vec3 direction) {
    float f = camera_footprint(eye, pixel, size);
    bool valid = camera_ray_at(eye, pixel + camera_subpixel(i) * max(f, 1.0), size, camera_lens(i), origin, direction);
    return valid && f > 0.0;
}

// The sample's central ray (footprint centre, lens centre).
bool camera_ray(int eye, vec2 pixel, vec2 size, out vec3 origin, out vec3 direction) {
    bool valid = camera_ray_at(eye, pixel, size, vec2(0.0), origin, direction);
    return valid && camera_footprint(eye, pixel, size) > 0.0;
}

// The directions of the rays one footprint step right (+x) and up (+y) of sub-ray i, through the
// same lens point, so from the same origin: the footprint texture LOD needs (Mitsuba's d_x, d_y).
void camera_subray_neighbours(int eye, vec2 pixel, vec2 size, uint i, out vec3 direction_x, out vec3 direction_y) {
    float f = max(camera_footprint(eye, pixel, size), 1.0);
    vec2 at = pixel + camera_subpixel(i) * f, lens = camera_lens(i);
    vec3 o;
    camera_ray_at(eye, at + vec2(f, 0.0), size, lens, o, direction_x);
    camera_ray_at(eye, at + vec2(0.0, f), size, lens, o, direction_y);
}

void camera_ray_neighbours(int eye, vec2 pixel, vec2 size, out vec3 direction_x, out vec3 direction_y) {
    float f = max(camera_footprint(eye, pixel, size), 1.0);
    vec3 o;
    camera_ray_at(eye, pixel + vec2(f, 0.0), size, vec2(0.0), o, direction_x);
    camera_ray_at(eye, pixel + vec2(0.0, f), size, vec2(0.0), o, direction_y);
}

// Kept for shaders written before camera models: new code calls camera_ray(), which also gives
// the origin and whether the sample makes a ray at all.
vec3 eye_ray_direction(int eye, vec2 pixel, vec2 size) {
    vec3 origin, direction;
    camera_ray(eye, pixel, size, origin, direction);
    return direction;
}

vec3 eye_forward(int eye) { return -eye_rotation[eye][2]; }

// A frame's depth per unit of distance along unit ray direction d: view depth (along the view
// axis, as the rasterizer's near and far planes) for the planar models; for the wide model, whose
// rays reach sideways and backwards, depth is the distance itself (near and far are spheres).
float camera_depth_per_distance(int eye, vec3 d) {
#if CAMERA_MODEL == CAMERA_WIDE
    return 1.0;
#else
    return dot(d, eye_forward(eye));
#endif
}

// Reversed-Z depth value -> linear view depth (see rayvr/frame/cameras/rig.py projection()).
float eye_view_depth(float z) {
    float n = eye_depth.x, f = eye_depth.y;
    return f == 0.0 ? n / z : n * f / (z * (f - n) + n);
}

// The chosen model's code, last: the model files skipped by the #if still count lines, which
// would shift the line numbers of anything after them in this file in compile errors. Shared
// model code comes first: the loader includes a file once, even where an #if drops that copy.
#include "../cameras/planar.glsl"
#if CAMERA_MODEL == CAMERA_PINHOLE
#include "../cameras/pinhole.glsl"
#elif CAMERA_MODEL == CAMERA_DISTORTED
#include "../cameras/distorted.glsl"
#elif CAMERA_MODEL == CAMERA_WIDE
#include "../cameras/wide.glsl"
#elif CAMERA_MODEL == CAMERA_FOVEATED
#include "../cameras/foveated.glsl"
#elif CAMERA_MODEL == CAMERA_DOF
#include "../cameras/thin_lens.glsl"
#endif

#endif
