// Foveated samples (rayvr/frame/cameras/foveated.py): the pinhole's rays, at the pixels whose
// ordered-dither rank lies below the density the linear MAR model asks for there.
uniform vec2 camera_gaze;  // gaze point, fraction of the image (GL: y up)
uniform vec3 camera_mar;   // fovea MAR (degrees), MAR slope, fovea radius (degrees)

bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction) {
    origin = eye_position[eye];
    direction = pinhole_direction(eye, pixel, size);
    return true;
}

// Samples per pixel at pixel centre `pixel` (foveated.py density).
float foveated_density(int eye, vec2 pixel, vec2 size) {
    vec3 d = pinhole_direction(eye, pixel, size);
    vec3 g = pinhole_direction(eye, camera_gaze * size, size);
    float ecc = degrees(atan(length(cross(d, g)), dot(d, g)));
    vec4 t = eye_tangents[eye];
    vec2 tan_xy = mix(t.xz, t.yw, pixel / size);
    float step_angle = sqrt((t.y - t.x) / size.x * (t.w - t.z) / size.y);
    float pixel_angle = degrees(step_angle / pow(1.0 + dot(tan_xy, tan_xy), 0.75));
    float mar = camera_mar.x + camera_mar.y * max(ecc - camera_mar.z, 0.0);
    return clamp(pow(pixel_angle / mar, 2.0), 1.0 / float(DITHER_LEVELS), 1.0);
}

// Ordered-dither rank in [0, DITHER_LEVELS) (foveated.py dither_rank; DITHER_*: its declarations).
uint foveated_rank(ivec2 p) {
    uint rank = 0u;
    for (int i = 0; i < DITHER_BITS; i++) {
        uint bx = uint(p.x >> i) & 1u, by = uint(p.y >> i) & 1u;
        uint m = by == 0u ? 2u * bx : 3u - 2u * bx;  // Bayer 2x2: [[0, 2], [3, 1]]
        rank += m << (2 * (DITHER_BITS - 1 - i));
    }
    return rank;
}

float camera_footprint(int eye, vec2 pixel, vec2 size) {
    float rho = foveated_density(eye, pixel, size);
    bool edge = pixel.x > size.x - 1.0 || pixel.y > size.y - 1.0;  // last column, top row: cells stay closed
    return edge || (float(foveated_rank(ivec2(pixel))) + 0.5) / float(DITHER_LEVELS) < rho ? inversesqrt(rho) : 0.0;
}
