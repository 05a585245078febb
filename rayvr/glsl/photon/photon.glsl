// Photon records and the hash grid's cell index (rayvr/accel/photon_map.py holds the numpy twin).
//   Photon: position xyz, surface normal (octahedral snorm16x2 bits), power rgb, extra word:
//   1 = a stored photon in the traced slots (0 = empty slot), the split axis in the kd-tree's array.
//   Grid: cells of side 1 / grid_inv_cell from grid_origin, grid_dims per axis with one empty cell
//   of padding on each side; cell = z * nx * ny + y * nx + x (photon-mapping paper, eq. 2).
#ifndef RAYVR_PHOTON_GLSL
#define RAYVR_PHOTON_GLSL
#include "../layout.glsl"

struct Photon {
    vec4 position_normal;  // xyz scene-local, w normal bits
    vec4 power_extra;      // rgb power (flux), w extra bits
};

uint oct_encode(vec3 n) {
    vec3 m = n / max(abs(n.x) + abs(n.y) + abs(n.z), 1e-30);
    vec2 xy = m.z >= 0.0 ? m.xy : (1.0 - abs(m.yx)) * mix(vec2(-1.0), vec2(1.0), greaterThanEqual(m.xy, vec2(0.0)));
    return packSnorm2x16(xy);
}

vec3 oct_decode(uint bits) {
    vec2 xy = unpackSnorm2x16(bits);
    vec3 n = vec3(xy, 1.0 - abs(xy.x) - abs(xy.y));
    float t = max(-n.z, 0.0);
    n.xy += mix(vec2(t), vec2(-t), greaterThanEqual(n.xy, vec2(0.0)));
    return normalize(n);
}

vec3 photon_position(Photon p) { return p.position_normal.xyz; }
vec3 photon_normal(Photon p) { return oct_decode(floatBitsToUint(p.position_normal.w)); }
vec3 photon_power(Photon p) { return p.power_extra.rgb; }
uint photon_extra(Photon p) { return floatBitsToUint(p.power_extra.w); }

uniform vec3 grid_origin;
uniform float grid_inv_cell;
uniform ivec3 grid_dims;

// Clamped to the inner cells: the 3x3x3 neighbourhood never leaves the grid (no bounds checks).
ivec3 grid_coord(vec3 p) {
    return clamp(ivec3(floor((p - grid_origin) * grid_inv_cell)), ivec3(1), grid_dims - 2);
}

uint grid_index(ivec3 c) {
    return uint((c.z * grid_dims.y + c.y) * grid_dims.x + c.x);
}

uint grid_cell(vec3 p) { return grid_index(grid_coord(p)); }

uint grid_dead_key() { return uint(grid_dims.x * grid_dims.y * grid_dims.z); }

#endif
