// `photon` (rayvr/effects/photon.py) in the wavefront of rt/wave_shade.comp: after the pixel's
// direct light with shadow rays, emission plus the photon map's indirect light and caustics --
// albedo / pi * irradiance within the material's radius (glsl/photon/estimate.glsl) -- in place
// of the ambient term. No reflection paths.
#include "../photon/estimate.glsl"

void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng) {
    float r = material_param_float(mi, PARAM_RADIUS);  // scene units
    vec3 e = photon_irradiance(s.position, ng, r, material_param_int(mi, PARAM_ESTIMATOR),
                               material_param_int(mi, PARAM_K));
    wave_paths[i].radiance = vec4(s.emission + s.base_color * (1.0 - s.metallic) / PI * e, 0.0);
}
