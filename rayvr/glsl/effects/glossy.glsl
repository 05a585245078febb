// `glossy` (rayvr/frame/effects/glossy.py) in the wavefront of rt/wave_shade.comp: `samples` GGX
// reflection paths per pixel by VNDF importance sampling (path j of pixel i is item j * n + i),
// each weighted by F * G2/G1 / samples; the ambient term lights only the diffuse share.
// A rect light is found both by the pixel's light samples and by the GGX rays that reach its
// emitter: MIS (power heuristic, common/mis.glsl) weighs the GGX lobe's share of each, so its
// highlight is counted once (the Lambert lobe is only light-sampled: weight 1).

// Included without LIGHT_MIS (ssr's glossy rays), the light samples and GGX rays are not weighed.
#ifdef LIGHT_MIS
// lighting.glsl's rect-light samples: the specular lobe weighed against the surface's
// mis_bsdf_samples VNDF rays.
vec3 light_mis_brdf_cos(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness, float light_pdf) {
    vec3 diffuse, spec;
    brdf_cos_lobes(n, v, l, base_color, metallic, roughness, diffuse, spec);
    if (mis_bsdf_samples <= 0.0) return diffuse + spec;
    float bsdf_pdf = mis_bsdf_samples * ggx_vndf_pdf(n, v, l, max(roughness * roughness, 1e-3));
    return diffuse + spec * power_heuristic(light_pdf, bsdf_pdf);
}
#endif

void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng) {
    wave_paths[i].radiance = vec4(s.emission + ambient * s.base_color * (1.0 - s.metallic), 0.0);
    vec3 f0 = mix(vec3(0.04), s.base_color, s.metallic);
    int samples = max(material_param_int(mi, PARAM_SAMPLES), 1);
    float alpha = max(s.roughness * s.roughness, 1e-3);
    mat3 tbn = basis_around(s.normal);
    vec3 v_local = v * tbn;  // transpose(tbn) * v
    v_local.z = max(v_local.z, 1e-4);
    for (int j = 0; j < int(wave_paths_per_pixel); ++j) {
        uint p;
        if (!pixel_path(i, j, samples, p)) continue;
        vec3 m = tbn * sample_ggx_vndf(normalize(v_local), alpha, rng_next2(rng));
        vec3 l = reflect(-v, m);
        float n_l = dot(s.normal, l);
        if (n_l <= 0.0 || dot(l, ng) <= 0.0) {  // below the surface: no light this way
            end_path(p);
            continue;
        }
        vec3 weight = fresnel_schlick(f0, dot(v, m)) * smith_g2_over_g1(v_local.z, n_l, alpha);
        start_path(p, s.position, ng, l, weight / float(samples));
#ifdef LIGHT_MIS
        wave_paths[p].radiance.w = float(samples) * ggx_vndf_pdf(s.normal, v, l, alpha);  // for MIS at its hit
#endif
    }
}
