// Thin-lens depth of field (rayvr/frame/cameras/thin_lens.py): from lens point `lens` (unit disk,
// scaled by the aperture) through the pinhole ray's point at view depth `focus`.
uniform vec2 camera_thin_lens;  // aperture radius, focus distance (world units)

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    vec3 d = pinhole_direction(eye, pixel, size);
    vec3 focal = d * (camera_thin_lens.y / dot(d, eye_forward(eye)));
    vec3 offset = camera_thin_lens.x * (lens.x * eye_rotation[eye][0] + lens.y * eye_rotation[eye][1]);
    origin = eye_position[eye] + offset;
    direction = normalize(focal - offset);
    return true;
}

float camera_footprint(int eye, vec2 pixel, vec2 size) { return 1.0; }
