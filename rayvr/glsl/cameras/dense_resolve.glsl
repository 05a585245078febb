// The resolve of a camera model whose samples cover every pixel (no `reconstruction`): the
// accumulated sum as it is. Included by shade/sample_resolve.comp.
void camera_resolve(ivec3 p, ivec2 n) { imageStore(frame_hdr, p, vec4(imageLoad(sum, p).rgb, 1.0)); }
