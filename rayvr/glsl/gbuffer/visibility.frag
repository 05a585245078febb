#version 430
// Visibility raster: only the triangle ID (and depth). The other G-buffer channels are filled
// by gbuffer/resolve.comp: on GPUs whose raster back end is narrow (the NVIDIA GPUs measured write ~57 GB/s
// through it against TB/s from compute) writing 8 bytes per pixel here instead of 56 pays off.
layout(location = 0) out uint out_triangle;

void main() {
    out_triangle = uint(gl_PrimitiveID);
}
