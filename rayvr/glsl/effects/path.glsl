// `path` (rayvr/frame/effects/path.py) in the wavefront of rt/wave_shade.comp: `samples` paths per
// pixel (path j of pixel i is item j * n + i). At every vertex: the surface's emission, next-event
// estimation (lighting.glsl's light samples, `area_samples` per rect light, shadow rays; at the
// pixel's own surface area_samples x samples, one stratified lattice for all its paths) and one
// BSDF sample (common/mis.glsl: Lambert or GGX lobe) to go on; rect lights are found both ways and
// weighed by the power heuristic. Russian roulette from bounce `rr_start`, at most `bounces`
// bounces after the pixel's surface. No ambient term: the traced paths are the indirect light.
// Random numbers: the pixel's stream (seeded from its surface point: the same in both eyes)
// hashed with the path's index j and the bounce, so every vertex draws its own samples.
#define EFFECT_PATH_VERTEX

vec3 light_mis_brdf_cos(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness, float light_pdf) {
    vec3 f = brdf_cos(n, v, l, base_color, metallic, roughness);
    if (mis_bsdf_samples <= 0.0) return f;
    return f * power_heuristic(light_pdf, mis_bsdf_samples * brdf_pdf(n, v, l, base_color, metallic, roughness));
}

uint path_rng(uint pixel_rng, uint j, int vertex) {
    return pcg_hash(pixel_rng ^ pcg_hash(j * 131u + uint(vertex) + 0x9E3779B9u));
}

// Path p leaves surface s (geometric normal ng on the viewer's side) along a BSDF sample;
// `count` BSDF samples were taken at s (for the MIS weight at the next hit).
void path_scatter(uint p, Surface s, vec3 v, vec3 ng, inout uint rng, vec3 throughput, float count) {
    vec3 u = vec3(rng_next2(rng), rng_next(rng));
    vec3 l = sample_brdf(s.normal, v, s.base_color, s.metallic, s.roughness, u);
    float pdf = brdf_pdf(s.normal, v, l, s.base_color, s.metallic, s.roughness);
    if (!(pdf > 0.0) || dot(l, ng) <= 0.0) {  // below the surface: nothing reflects that way
        end_path(p);
        return;
    }
    vec3 weight = throughput * brdf_cos(s.normal, v, l, s.base_color, s.metallic, s.roughness) / pdf;
    start_path(p, s.position, ng, l, weight);
    wave_paths[p].radiance.w = count * pdf;
}

void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng) {
    wave_paths[i].radiance = vec4(s.emission, 0.0);
    int samples = max(material_param_int(mi, PARAM_SAMPLES), 1);
    for (int j = 0; j < int(wave_paths_per_pixel); ++j) {
        uint p;
        if (!pixel_path(i, j, samples, p)) continue;
        uint r = path_rng(rng, uint(j), 0);
        path_scatter(p, s, v, ng, r, vec3(1.0 / float(samples)), float(samples));
    }
}

#if WAVE_STAGE == 4
bool path_last_vertex(uint mi) {
    return wave_bounce >= max(material_param_int(mi, PARAM_BOUNCES), 1) - 1;
}

void path_vertex_begin(uint p, uint mi, ivec3 px, inout uint rng) {
    rng = path_rng(rng, p / wave_args[0].w, wave_bounce + 1);
    light_samples_begin(rng);  // this vertex's own light samples
    mis_bsdf_samples = path_last_vertex(mi) ? 0.0 : 1.0;  // the last vertex takes no BSDF sample
}

void path_vertex_end(uint p, Surface s, vec3 v, vec3 hng, uint mi, inout uint rng, vec3 throughput) {
    float samples = float(max(material_param_int(mi, PARAM_SAMPLES), 1));
    // light samples the previous vertex took (the pixel's surface: a set per path)
    float light_count = float(shadow_area_samples) * (wave_bounce == 0 ? samples : 1.0);
    wave_paths[p].radiance.rgb += throughput * s.emission *
        emission_mis_weight(wave_paths[p].origin.xyz, -v, s.position, wave_paths[p].radiance.w, light_count);
    if (path_last_vertex(mi)) {
        end_path(p);
        return;
    }
    if (wave_bounce + 1 >= material_param_int(mi, PARAM_RR_START)) {
        // survive with the path's weight relative to one sample's (throughput x samples), at most 0.95
        float q = min(max(throughput.r, max(throughput.g, throughput.b)) * samples, 0.95);
        if (!(rng_next(rng) < q)) {
            end_path(p);
            return;
        }
        throughput /= q;
    }
    path_scatter(p, s, v, hng, rng, throughput, 1.0);
}
#endif
