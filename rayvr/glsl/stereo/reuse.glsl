// Stereo `reuse` (photon-mapping paper §3.3; rayvr/frame/passes/reuse.py): which right-eye pixels take
// the left eye's shading. reuse_map[i] for right-eye pixel i = x + y * width (GL rows) is the
// left-eye pixel (same indexing) whose hit lands there and is visible from the right eye, or
// REUSE_NONE: the right eye shades it itself. reuse_map[width * height + i] is, while the map is
// made, the smallest distance (squared, float bits) of a landing from the pixel's centre.
// `classify` and `shade` skip the taken pixels (STEREO_REUSE), so no right-eye pixel is shaded twice.
#ifndef RAYVR_STEREO_REUSE_GLSL
#define RAYVR_STEREO_REUSE_GLSL
#include "../layout.glsl"  // REUSE_NONE: rayvr/frame/passes/reuse.py
#ifndef REUSE_ACCESS
#define REUSE_ACCESS readonly
#endif
layout(std430, binding = SSBO_REUSE_MAP) REUSE_ACCESS restrict buffer ReuseMap { uint reuse_map[]; };

// True for a right-eye pixel (layer 1) of an image `width` wide that takes a left-eye pixel's shading.
bool reuse_taken(ivec3 p, int width) {
    return p.z == 1 && reuse_map[uint(p.x + p.y * width)] != REUSE_NONE;
}

#endif
