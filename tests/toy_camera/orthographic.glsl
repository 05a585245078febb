// The orthographic camera of tests/toy_camera/orthographic.py, a model from outside rayvr: included
// by rayvr's glsl/common/camera.glsl through CAMERA_MODEL_FILE (this file's absolute path).
uniform float camera_height;  // the image plane's vertical extent, world units

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    vec2 s = (pixel / size - 0.5) * vec2(size.x / size.y, 1.0) * camera_height;
    origin = eye_position[eye] + eye_rotation[eye] * vec3(s, 0.0);
    direction = -eye_rotation[eye][2];
    return true;
}

float camera_footprint(int eye, vec2 pixel, vec2 size) { return 1.0; }
