#version 430
// Ray-traced primary visibility: the camera rays of common/camera.glsl (the rays the rasterizer
// samples) through the BVH, writing what the G-buffer resolve needs: the triangle ID, and the
// hit distance in position.w (its fallback when the triangle is seen edge-on). The resolve
// (gbuffer/resolve.comp with PRIMARY_RAYS) then fills every channel as for the raster path.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "../layout.glsl"
#include "../accel/bvh.glsl"
#include "../common/camera.glsl"

layout(rgba32f, binding = GB_IMAGE_POSITION) uniform writeonly image2DArray img_position;
layout(r32ui, binding = GB_IMAGE_TRIANGLE) uniform writeonly uimage2DArray img_triangle;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec2 size = imageSize(img_triangle).xy;
    if (any(greaterThanEqual(p.xy, size))) return;
    vec3 o, d;
    if (!camera_ray(p.z, vec2(p.xy) + 0.5, vec2(size), o, d)) {  // a sample of the model that makes no ray
        imageStore(img_triangle, p, uvec4(BVH_MISS));
        imageStore(img_position, p, vec4(0.0));
        return;
    }
    Ray r = Ray(o, 0.0, d, 3.0e38);
    if (eye_depth.y > 0.0)  // a finite far plane clips as the rasterizer does (along the view axis)
        r.tmax = eye_depth.y / max(dot(r.direction, eye_forward(p.z)), 1e-30);
    r.tmin = eye_depth.x / max(dot(r.direction, eye_forward(p.z)), 1e-30);
    Hit h;
    trace_closest(r, h);
    imageStore(img_triangle, p, uvec4(h.prim));
    imageStore(img_position, p, vec4(0.0, 0.0, 0.0, h.t));
}
