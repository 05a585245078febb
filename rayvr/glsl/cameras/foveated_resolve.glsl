// The foveated camera's fill for display (frame/cameras/foveated.py: its `reconstruction`, and
// `reconstruct` the numpy twin), included by shade/sample_resolve.comp: the pixels between samples
// filled coarse to fine, level by level. The samples' nested dither lattices are complete down to
// some stride and partial below it, so a fill must use every sample as a corner of the cells
// around it: filling each pixel from the finest cell whose four corners were all samples skipped
// the samples of a partial lattice inside it, which stood out as single dots of their own colour
// amid the fill wherever the image has an edge. Dispatches (Foveated.resolve_steps):
//   resolve_level = DITHER_BITS   copy the samples into `fill` (the stride-2^DITHER_BITS lattice is all samples)
//   level k, resolve_step 0       the centres of the stride-2^(k+1) cells (both coordinates odd
//                                 multiples of 2^k) that are not samples: the mean of the linear
//                                 fills between the cell's opposite edge midpoints along x and
//                                 along y, each midpoint its sample or, if it is none, linear
//                                 between the cell corners beside it (cut at the image's last
//                                 column / top row, all samples): bilinear when no midpoint is one
//   level k, resolve_step 1       the cells' edge midpoints (one coordinate an odd multiple): the
//                                 mean of the linear fills between their neighbours 2^k away along
//                                 x and along y (cell corners and centres: diamond-square; on the
//                                 image's first column / row, along its edge only)
// Every rule is exact on an image linear in the fill's units.
// each point a sample or filled by a dispatch before; level 0's step 1 also writes the frame.
// The fill is made in display-like units (compress, expand) and expanded back: in linear HDR an
// emitter's samples (10x the white point) outweigh every dark sample beside them, so the fill
// between them displayed white and the dark samples stood alone.

// `fill`: the samples (alpha 1), then the points filled so far (alpha FILLED).
#define FILLED 0.5
uniform int resolve_level;
uniform int resolve_step;

vec4 fill_at(ivec2 q, int eye) { return imageLoad(fill, ivec3(q, eye)); }

// Linear between the points s before and s after p along `axis` (the one after cut at the image).
vec3 fill_between(ivec3 p, int axis, int s, ivec2 n) {
    ivec2 a = p.xy, b = p.xy;
    a[axis] -= s;
    b[axis] = min(b[axis] + s, n[axis] - 1);
    return mix(fill_at(a, p.z).rgb, fill_at(b, p.z).rgb, float(s) / float(b[axis] - a[axis]));
}

// A cell centre p's edge midpoint m (along `axis`): its sample, or (not filled yet) linear between
// the cell corners beside it.
vec3 midpoint(ivec3 p, ivec2 m, int axis, int s, ivec2 n) {
    vec4 v = fill_at(m, p.z);
    return v.a == 1.0 ? v.rgb : fill_between(ivec3(m, p.z), 1 - axis, s, n);
}

void camera_resolve(ivec3 p, ivec2 n) {
    if (resolve_level == DITHER_BITS) {
        bool is_one = is_sample(p.z, p.xy, vec2(n));
        imageStore(fill, p, is_one ? vec4(compress(imageLoad(sum, p).rgb), 1.0) : vec4(0.0));
        return;
    }
    bool sampled = imageLoad(fill, p).a == 1.0;  // the pattern, once (the copy marks the samples)
    int s = 1 << resolve_level;
    ivec2 odd = (p.xy / s) & 1;
    bool on_lattice = all(equal(p.xy % s, ivec2(0)));
    bool centre = on_lattice && odd.x == 1 && odd.y == 1, edge = on_lattice && (odd.x ^ odd.y) == 1;
    bool last = resolve_level == 0 && resolve_step == 1;  // writes the frame
    if (resolve_step == 0 && centre && !sampled) {
        vec3 c = vec3(0.0);
        for (int axis = 0; axis < 2; axis++) {
            ivec2 a = p.xy, b = p.xy;
            a[axis] -= s;
            b[axis] = min(b[axis] + s, n[axis] - 1);
            c += 0.5 * mix(midpoint(p, a, axis, s, n), midpoint(p, b, axis, s, n), float(s) / float(b[axis] - a[axis]));
        }
        imageStore(fill, p, vec4(c, FILLED));
    } else if (resolve_step == 1 && edge && !sampled) {
        // On the image's first column or row the neighbour before is outside: the other axis alone.
        vec3 c = p.x == 0 ? fill_between(p, 1, s, n) : p.y == 0 ? fill_between(p, 0, s, n)
               : 0.5 * (fill_between(p, 0, s, n) + fill_between(p, 1, s, n));
        if (last)
            imageStore(frame_hdr, p, vec4(expand(c), 1.0));
        else
            imageStore(fill, p, vec4(c, FILLED));
    } else if (last) {
        imageStore(frame_hdr, p, vec4(sampled ? imageLoad(sum, p).rgb : expand(imageLoad(fill, p).rgb), 1.0));
    }
}
