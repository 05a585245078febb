// Pinhole camera model (rayvr/cameras/pinhole.py): rays from the eye through pixel centres on
// the plane z = -1 of the eye's frustum tangents, i.e. the rays the rasterizer samples. Included
// by common/camera.glsl (CAMERA_MODEL CAMERA_PINHOLE), whose per-eye uniforms it reads and
// whose camera_ray / camera_ray_neighbours declarations it implements.
// `pixel` in GL image coordinates (x right, y up; centres at +0.5), `size` the image size.

vec3 pinhole_direction(int eye, vec2 pixel, vec2 size) {
    vec4 t = eye_tangents[eye];
    vec2 f = pixel / size;
    vec3 d = vec3(mix(t.x, t.y, f.x), mix(t.z, t.w, f.y), -1.0);
    return normalize(eye_rotation[eye] * d);
}

bool camera_ray(int eye, vec2 pixel, vec2 size, out vec3 origin, out vec3 direction) {
    origin = eye_position[eye];
    direction = pinhole_direction(eye, pixel, size);
    return true;  // every pixel of a plane has a ray
}

// The neighbours are true pixel rays, so the resolve's texture LOD stays what it was.
void camera_ray_neighbours(int eye, vec2 pixel, vec2 size, out vec3 direction_x, out vec3 direction_y) {
    direction_x = pinhole_direction(eye, pixel + vec2(1.0, 0.0), size);
    direction_y = pinhole_direction(eye, pixel + vec2(0.0, 1.0), size);
}
