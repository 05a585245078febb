// The checkerboard camera of tests/toy_camera/checkerboard.py, a model from outside rayvr: the
// pinhole's rays (pinhole_direction: rayvr's cameras/planar.glsl, which common/camera.glsl
// includes first) at the pixels whose x + y has the parity asked for.
uniform int camera_parity;  // 0: x + y even, 1: odd

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    origin = eye_position[eye];
    direction = pinhole_direction(eye, pixel, size);
    return true;
}

float camera_footprint(int eye, vec2 pixel, vec2 size) {
    ivec2 q = ivec2(pixel);
    return ((q.x + q.y) & 1) == camera_parity ? 1.0 : 0.0;
}
