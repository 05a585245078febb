// Watertight ray-triangle intersection (Woop, Benthin & Wald, JCGT 2013).
// The ray is sheared so it becomes the +z axis through the origin; each vertex is transformed the
// same way whichever triangle it belongs to, and the 2D edge functions of a shared edge come out as
// exact negatives of each other, so a ray through an edge or vertex hits at least one triangle.
#ifndef RAYVR_ACCEL_TRIANGLE_GLSL
#define RAYVR_ACCEL_TRIANGLE_GLSL

#include "ray.glsl"

struct RayShear {     // per-ray constants of the test
    vec3 origin;
    vec3 direction;
    int kx, ky, kz;   // ray-space axes: kz = largest |direction| component
    vec3 S;           // shear (dx/dz, dy/dz) and scale 1/dz
};

RayShear ray_shear(Ray r) {
    vec3 d = r.direction;
    vec3 a = abs(d);
    RayShear s;
    s.origin = r.origin;
    s.direction = d;
    s.kz = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
    s.kx = s.kz == 2 ? 0 : s.kz + 1;
    s.ky = s.kx == 2 ? 0 : s.kx + 1;
    if (d[s.kz] < 0.0) {   // keep the winding (sign of the edge functions) the same
        int k = s.kx; s.kx = s.ky; s.ky = k;
    }
    s.S = vec3(d[s.kx] / d[s.kz], d[s.ky] / d[s.kz], 1.0 / d[s.kz]);
    return s;
}

// Hit with tmin < t < tmax? uv = barycentric weights of v1 and v2. No backface culling.
bool intersect_triangle(RayShear s, vec3 v0, vec3 v1, vec3 v2, float tmin, float tmax,
                        out float t, out vec2 uv) {
    vec3 A = v0 - s.origin;
    vec3 B = v1 - s.origin;
    vec3 C = v2 - s.origin;
    // `precise` forbids fused multiply-adds: with them a shared edge's function would not be the exact
    // negation of itself seen from the neighbour triangle, and rays could slip through the edge.
    precise float ax = A[s.kx] - s.S.x * A[s.kz];
    precise float ay = A[s.ky] - s.S.y * A[s.kz];
    precise float bx = B[s.kx] - s.S.x * B[s.kz];
    precise float by = B[s.ky] - s.S.y * B[s.kz];
    precise float cx = C[s.kx] - s.S.x * C[s.kz];
    precise float cy = C[s.ky] - s.S.y * C[s.kz];
    precise float U = cx * by - cy * bx;   // weight of v0
    precise float V = ax * cy - ay * cx;   // weight of v1
    precise float W = bx * ay - by * ax;   // weight of v2
    if (U == 0.0 || V == 0.0 || W == 0.0) {
        // The ray passes (within float rounding) through an edge: decide in double, as the paper does.
        U = float(double(cx) * double(by) - double(cy) * double(bx));
        V = float(double(ax) * double(cy) - double(ay) * double(cx));
        W = float(double(bx) * double(ay) - double(by) * double(ax));
    }
    t = 0.0;
    uv = vec2(0.0);
    if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0))
        return false;
    float det = U + V + W;
    if (det == 0.0)   // degenerate triangle, or the ray lies in its plane
        return false;
    // Distance from the triangle's plane rather than the paper's barycentric blend of vertex depths:
    // for large triangles seen at grazing angles that blend loses ~1e-4 relative accuracy in float,
    // the plane equation keeps the error near eps * |v0 - origin|. The inside test above is unchanged,
    // so watertightness holds; a NaN/inf t (ray in the plane) fails the range test.
    vec3 n = cross(v1 - v0, v2 - v0);
    t = dot(n, A) / dot(n, s.direction);
    if (!(t > tmin && t < tmax))
        return false;
    uv = vec2(V, W) / det;
    return true;
}

#endif
