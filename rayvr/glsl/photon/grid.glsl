// Search the hash grid (photon-mapping paper §3.1): the 3x3x3 cells around q as 9 runs of three
// cells adjacent in x, which are contiguous in the sorted photon map (photon_start[c] ..
// photon_start[c + 3]). Every photon closer than sqrt(photon_search_r2()) goes to photon_visit;
// both are the includer's (glsl/photon/estimate.glsl; the tests' photon_query.comp).
#ifndef RAYVR_PHOTON_GRID_GLSL
#define RAYVR_PHOTON_GRID_GLSL
#include "photon.glsl"

layout(std430, binding = SSBO_PHOTON_MAP) readonly restrict buffer PhotonMap { Photon photon_map[]; };
layout(std430, binding = SSBO_PHOTON_SCAN) readonly restrict buffer PhotonStart { uint photon_start[]; };

float photon_search_r2();
void photon_visit(uint index, Photon p, float d2);

void grid_search(vec3 q) {
    ivec3 c = grid_coord(q);
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy) {
            uint row = grid_index(c + ivec3(-1, dy, dz));
            uint end = photon_start[row + 3u];
            for (uint i = photon_start[row]; i < end; ++i) {
                Photon p = photon_map[i];
                vec3 d = photon_position(p) - q;
                float d2 = dot(d, d);
                if (d2 <= photon_search_r2()) photon_visit(i, p, d2);
            }
        }
}

#endif
