// Per-eye camera data and primary-ray generation, shared by every pass that needs the camera's
// rays (ray-traced primary visibility, G-buffer resolve, shading). The rays come from the camera
// model whose `defines()` the program is built with (rayvr/frame/cameras/base.py; none: the pinhole):
// CAMERA_MODEL, its CAMERA_<NAME> id; CAMERA_MODEL_FILE, its GLSL file (under glsl/ or absolute),
// which implements camera_ray_at and camera_footprint; CAMERA_DEPTH_ALONG_RAY, a capability it
// declares. Uniform values: rayvr/frame/cameras/base.py uniforms().
#ifndef RAYVR_CAMERA_GLSL
#define RAYVR_CAMERA_GLSL

uniform vec3 eye_position[2];  // scene-local (world - scene origin)
uniform mat3 eye_rotation[2];  // camera-to-world; columns right, up, back
uniform vec4 eye_tangents[2];  // frustum tangents: left, right, bottom, top
uniform vec2 eye_depth;        // near, far (0: infinite far plane)
uniform int camera_channel;    // the colour channel set this frame round samples (CameraModel.channels)
// camera_subray of a sub-ray of another channel set (CHANNEL_SAMPLES below) names its set here while
// it makes the ray; -1: camera_channel.
int camera_channel_override = -1;
// The colour channel set whose rays camera_ray_at makes: what a model with channels reads.
int camera_sample_channel() { return camera_channel_override >= 0 ? camera_channel_override : camera_channel; }

// One id per registered model, CAMERA_<NAME> = 1, 2, ... (layout.glsl: register_camera_model
// declares them), so a shader may still ask which model it is built for.
#include "../layout.glsl"
#ifndef CAMERA_MODEL
#define CAMERA_MODEL CAMERA_PINHOLE  // and the include of the model's file below takes pinhole.glsl
#elif !defined(CAMERA_MODEL_FILE)
#error CAMERA_MODEL without CAMERA_MODEL_FILE: build the program with the camera model's defines()
#endif
#ifndef CAMERA_DEPTH_ALONG_RAY
#define CAMERA_DEPTH_ALONG_RAY 0
#endif
#include "../cameras/sampling.glsl"

// The model's contract (rayvr/frame/cameras/base.py): the ray through continuous image position
// `pixel` (GL: x right, y up, centres at +0.5) and unit-disk lens point `lens`, and the footprint
// of the sample at a pixel centre (0: no sample there).
bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction);
float camera_footprint(int eye, vec2 pixel, vec2 size);

// CHANNEL_SAMPLES 3 (shared channel shading, frame/passes/primary_rays.py shares_channels): a sample's
// colour channel sets are cast together, as CAMERA_SUBRAYS = 3 x CAMERA_SUBSAMPLES sub-rays: three
// blocks of CAMERA_SUBSAMPLES, one a set, green's (SHARED_CHANNEL) first; 1: the round's set alone.
#ifndef CHANNEL_SAMPLES
#define CHANNEL_SAMPLES 1
#endif
#define CAMERA_SUBRAYS (CAMERA_SUBSAMPLES * CHANNEL_SAMPLES)

// The colour channel set of sub-ray i of CAMERA_SUBRAYS.
int camera_subray_channel(uint i) {
#if CHANNEL_SAMPLES > 1
    return int((i / uint(CAMERA_SUBSAMPLES) + uint(SHARED_CHANNEL)) % uint(CHANNEL_SAMPLES));
#else
    return camera_channel;
#endif
}

// Sub-ray i's footprint offset (cameras/sampling.glsl): each channel set's block has the same ones.
vec2 camera_subray_offset(uint i) { return camera_subpixel(i % uint(CAMERA_SUBSAMPLES)); }

// Sub-ray i of CAMERA_SUBRAYS of the sample at pixel centre `pixel` (cameras/sampling.glsl):
// scene-local origin, unit direction; false where the sample makes no ray.
bool camera_subray(int eye, vec2 pixel, vec2 size, uint i, out vec3 origin, out vec3 direction) {
#if CHANNEL_SAMPLES > 1
    camera_channel_override = camera_subray_channel(i);
    i %= uint(CAMERA_SUBSAMPLES);
#endif
    float f = camera_footprint(eye, pixel, size);
    bool valid = camera_ray_at(eye, pixel + camera_subpixel(i) * max(f, 1.0), size, camera_lens(i), origin, direction);
    camera_channel_override = -1;
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
#if CHANNEL_SAMPLES > 1
    camera_channel_override = camera_subray_channel(i);
    i %= uint(CAMERA_SUBSAMPLES);
#endif
    float f = max(camera_footprint(eye, pixel, size), 1.0);
    vec2 at = pixel + camera_subpixel(i) * f, lens = camera_lens(i);
    vec3 o;
    camera_ray_at(eye, at + vec2(f, 0.0), size, lens, o, direction_x);
    camera_ray_at(eye, at + vec2(0.0, f), size, lens, o, direction_y);
    camera_channel_override = -1;
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
// axis, as the rasterizer's near and far planes) for the planar models; for a model that declares
// depth_along_ray (the wide one, whose rays reach sideways and backwards), depth is the distance
// itself (near and far are spheres).
float camera_depth_per_distance(int eye, vec3 d) {
#if CAMERA_DEPTH_ALONG_RAY
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

// The model's code, last, after the planar models' shared code (pinhole_direction), which any
// model may call. The loader reads CAMERA_MODEL_FILE from the program's defines (a model's file
// outside rayvr is an absolute path); without it, the pinhole's.
#include "../cameras/planar.glsl"
#include CAMERA_MODEL_FILE or "../cameras/pinhole.glsl"

#endif
