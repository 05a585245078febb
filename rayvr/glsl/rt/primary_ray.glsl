// The ray a camera sub-ray traces in the frame (rt/primary.comp), shared with the frame's tile
// culling (accel/tile_cull.comp with TILE_CAMERA), which must bound exactly these rays. Needs
// accel/ray.glsl and common/camera.glsl included first.
#ifndef RAYVR_RT_PRIMARY_RAY_GLSL
#define RAYVR_RT_PRIMARY_RAY_GLSL

// From the near plane to the far plane (none for a far of 0), as the rasterizer clips, in the
// camera model's depth per unit distance.
Ray primary_ray(int eye, vec3 o, vec3 d) {
    Ray r = Ray(o, 0.0, d, 3.0e38);
    float along = max(camera_depth_per_distance(eye, d), 1e-30);
    if (eye_depth.y > 0.0) r.tmax = eye_depth.y / along;
    r.tmin = eye_depth.x / along;
    return r;
}

// The frame tile (TILE_W x TILE_H pixels, frame/passes/primary_rays.py) of pixel p (layer p.z) of an
// image of `size` per layer: tiles in order x, then y, then layer, as tile_cull.comp writes them.
uint primary_tile(ivec3 p, ivec2 size) {
    ivec2 n = (size + ivec2(TILE_W, TILE_H) - 1) / ivec2(TILE_W, TILE_H);
    return uint((p.z * n.y + p.y / TILE_H) * n.x + p.x / TILE_W);
}
#endif
