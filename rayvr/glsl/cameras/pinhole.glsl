// Pinhole camera model (rayvr/frame/cameras/pinhole.py): rays from the eye through positions on the
// plane z = -1 of the eye's frustum tangents, i.e. the rays the rasterizer samples. Included by
// common/camera.glsl (CAMERA_MODEL_FILE, and where a program has no model's defines); implements
// its model contract.
// pinhole_direction: cameras/planar.glsl (included by common/camera.glsl)

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    origin = eye_position[eye];
    direction = pinhole_direction(eye, pixel, size);
    return true;  // every point of a plane has a ray
}

float camera_footprint(int eye, vec2 pixel, vec2 size) { return 1.0; }
