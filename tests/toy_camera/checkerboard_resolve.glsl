// The checkerboard camera's fill for display (checkerboard.py: its `reconstruction`; `reconstruct`
// is the numpy twin), included by rayvr's shade/sample_resolve.comp, which declares the images
// (sum, fill, frame_hdr), compress / expand and is_sample. Two dispatches (resolve_steps):
//   resolve_step 0   each pixel's sample in display units into `fill` (0 at the gaps)
//   resolve_step 1   the frame: samples as they are, a gap the mean of its neighbours in the image
uniform int resolve_step;

void camera_resolve(ivec3 p, ivec2 n) {
    bool sampled = is_sample(p.z, p.xy, vec2(n));
    if (resolve_step == 0) {
        imageStore(fill, p, vec4(sampled ? compress(imageLoad(sum, p).rgb) : vec3(0.0), 1.0));
        return;
    }
    if (sampled) {
        imageStore(frame_hdr, p, vec4(imageLoad(sum, p).rgb, 1.0));
        return;
    }
    const ivec2 around[4] = ivec2[4](ivec2(-1, 0), ivec2(1, 0), ivec2(0, -1), ivec2(0, 1));
    vec3 total = vec3(0.0);
    float count = 0.0;
    for (int k = 0; k < 4; k++) {
        ivec2 q = p.xy + around[k];
        if (all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, n))) {
            total += imageLoad(fill, ivec3(q, p.z)).rgb;
            count += 1.0;
        }
    }
    imageStore(frame_hdr, p, vec4(expand(total / count), 1.0));
}
