// Sub-samples of a camera sample (rayvr/frame/cameras/sampling.py, which documents the set): sub-ray
// i of CAMERA_SUBSAMPLES has an offset in the sample's footprint (GL axes, footprint units) and
// a position on the lens (unit disk). The same for every pixel and both eyes.
#ifndef RAYVR_SAMPLING_GLSL
#define RAYVR_SAMPLING_GLSL
#ifndef CAMERA_SUBSAMPLES
#define CAMERA_SUBSAMPLES 1
#endif

float radical_inverse(uint i, uint base) {
    float out_value = 0.0, f = 1.0 / float(base);
    while (i > 0u) {
        out_value += f * float(i % base);
        i /= base;
        f /= float(base);
    }
    return out_value;
}

vec2 concentric_disk(vec2 uv) {
    vec2 ab = 2.0 * uv - 1.0;
    if (ab.x == 0.0 && ab.y == 0.0) return vec2(0.0);
    float r, phi;
    const float QUARTER_PI = 0.78539816339744831;
    if (abs(ab.x) > abs(ab.y)) { r = ab.x; phi = QUARTER_PI * (ab.y / ab.x); }
    else { r = ab.y; phi = 2.0 * QUARTER_PI - QUARTER_PI * (ab.x / ab.y); }
    return r * vec2(cos(phi), sin(phi));
}

vec2 camera_subpixel(uint i) {
    float n = float(CAMERA_SUBSAMPLES);
    return vec2((float(i) + 0.5) / n, radical_inverse(i, 2u) + 0.5 / n) - 0.5;
}

vec2 camera_lens(uint i) {
    return concentric_disk(fract(vec2(radical_inverse(i, 3u), radical_inverse(i, 5u)) + 0.5));
}
#endif
