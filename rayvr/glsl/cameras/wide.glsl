// Wide field of view (rayvr/frame/cameras/wide.py): equal pixel steps are equal angles; spherical
// section (yaw, pitch) or equidistant fisheye (angle from the axis grows with the radius).
uniform vec2 camera_fov;     // horizontal, vertical field of view, radians
uniform int camera_mapping;  // 0 spherical, 1 equidistant (wide.py MAPPINGS)

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    origin = eye_position[eye];
    vec2 a = (pixel / size - 0.5) * camera_fov;
    vec3 v;
    bool valid = true;
    if (camera_mapping == 0) {
        v = vec3(sin(a.x) * cos(a.y), sin(a.y), -cos(a.x) * cos(a.y));
    } else {
        float theta = length(a);
        float sinc = theta > 1e-8 ? sin(theta) / theta : 1.0;
        v = vec3(sinc * a, -cos(theta));
        valid = theta <= 3.14159265358979;
    }
    direction = normalize(eye_rotation[eye] * v);
    return valid;
}

float camera_footprint(int eye, vec2 pixel, vec2 size) { return 1.0; }
