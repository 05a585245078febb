// `shadows` (rayvr/frame/effects/shadows.py) in the wavefront of rt/wave_shade.comp: after the pixel's
// direct light with shadow rays, it adds emission and the ambient term, and traces no paths.
void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng) {
    wave_paths[i].radiance = vec4(s.emission + ambient * s.base_color, 0.0);
}
