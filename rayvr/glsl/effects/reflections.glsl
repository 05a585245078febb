// `reflections` (rayvr/frame/effects/reflections.py) in the wavefront of rt/wave_shade.comp: one mirror
// path per pixel, weighted by Fresnel; the ambient term lights only the diffuse share (the specular
// share is traced). Stage 4 follows the path through up to `bounces` reflective surfaces.
void effect_start_paths(uint i, Surface s, vec3 v, vec3 ng, uint mi, inout uint rng) {
    wave_paths[i].radiance = vec4(s.emission + ambient * s.base_color * (1.0 - s.metallic), 0.0);
    vec3 f0 = mix(vec3(0.04), s.base_color, s.metallic);
    vec3 dir = reflect(-v, s.normal);
    if (dot(dir, ng) <= 0.0) dir = reflect(dir, ng);  // a shading normal that points below: mirror on ng
    start_path(i, s.position, ng, dir, fresnel_schlick(f0, dot(s.normal, v)));
}
