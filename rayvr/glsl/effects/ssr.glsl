// `ssr` (rayvr/frame/effects/ssr.py) in the wavefront of rt/wave_shade.comp: the pixel event of
// `reflections` (one Fresnel-weighted mirror path), except on surfaces rougher than the material's
// `mirror_roughness` when `samples` > 0: that of `glossy` (`samples` GGX paths by VNDF importance
// sampling); the paths' rays are then traced through the quadtree first (rt/wave_trace.comp SSR_TRACE).
#define effect_start_paths mirror_start_paths
#include "reflections.glsl"
#undef effect_start_paths
#define effect_start_paths glossy_start_paths
#include "glossy.glsl"
#undef effect_start_paths

void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng) {
    if (s.roughness > material_param_float(mi, PARAM_MIRROR_ROUGHNESS) && material_param_int(mi, PARAM_SAMPLES) > 0) {
        glossy_start_paths(i, s, v, ng, mi, rng);
        return;
    }
    mirror_start_paths(i, s, v, ng, mi, rng);
    uint n = wave_args[0].w;
    for (uint j = 1u; j < wave_paths_per_pixel; ++j) {  // a mirror needs one path of the pixel's
        wave_paths[j * n + i].radiance = vec4(0.0);
        end_path(j * n + i);
    }
}

// The rays the pixel sent (wave_shade.comp spreads its area_samples over them at their hits): as
// effect_start_paths chose, `samples` GGX rays on a rough surface, else one mirror ray.
#define EFFECT_PIXEL_RAYS
int effect_pixel_rays(uint mi, ivec3 px) {
    int samples = material_param_int(mi, PARAM_SAMPLES);
    if (samples <= 0) return 1;
    return gbuffer_fetch(px).roughness > material_param_float(mi, PARAM_MIRROR_ROUGHNESS) ? samples : 1;
}
