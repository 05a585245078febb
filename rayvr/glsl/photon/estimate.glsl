// The photon density estimate (photon-mapping paper eq. 1) for a Lambertian surface: irradiance
// E = sum of photon power / (pi r^2) over the photons within r on the same side (n . n_p > 0);
// the radiance is albedo / pi * E. Estimators (accel/photon_map.ESTIMATORS):
//   0 grid         every photon within r, through the hash grid (no heap: the paper's fast one)
//   1 grid_heap    the k nearest within r (a max-heap of k), disc through the k-th (Jensen)
//   2 kdtree       every photon within r, through the kd-tree
//   3 kdtree_heap  the k nearest, through the kd-tree (the paper's baseline)
// accel/photon_map.density is the numpy reference. PHOTON_ESTIMATORS (bit i: estimator i may be
// asked for; frame/effects/photon/shade.py compiles the frame's set) leaves out the heap and the kd-tree
// walk when no material uses them: the grid-only kernel carries no heap arrays (registers).
#ifndef RAYVR_PHOTON_ESTIMATE_GLSL
#define RAYVR_PHOTON_ESTIMATE_GLSL
#include "grid.glsl"
#include "kdtree.glsl"

// PHOTON_MAX_K: layout.glsl (rayvr/accel/photon_map.py MAX_K)
// PHOTON_ESTIMATOR_<NAME>: estimator i of rayvr/accel/photon_map.py ESTIMATORS (layout.glsl)
#ifndef PHOTON_ESTIMATORS
#define PHOTON_ESTIMATORS ((1 << PHOTON_ESTIMATOR_COUNT) - 1)  // all
#endif
#define PHOTON_HEAP ((PHOTON_ESTIMATORS & ((1 << PHOTON_ESTIMATOR_GRID_HEAP) | (1 << PHOTON_ESTIMATOR_KDTREE_HEAP))) != 0)
#define PHOTON_KDTREE ((PHOTON_ESTIMATORS & ((1 << PHOTON_ESTIMATOR_KDTREE) | (1 << PHOTON_ESTIMATOR_KDTREE_HEAP))) != 0)

float est_r2;
vec3 est_normal;
vec3 est_sum;
#if PHOTON_HEAP
int est_k;  // 0: no heap
int heap_n;
float heap_d2[PHOTON_MAX_K];
vec3 heap_power[PHOTON_MAX_K];

float photon_search_r2() { return est_k > 0 && heap_n == est_k ? heap_d2[0] : est_r2; }
#else
const int est_k = 0;
float photon_search_r2() { return est_r2; }
#endif

#if PHOTON_HEAP
void heap_sift_down(int i) {
    while (true) {
        int l = 2 * i + 1, r = l + 1, m = i;
        if (l < heap_n && heap_d2[l] > heap_d2[m]) m = l;
        if (r < heap_n && heap_d2[r] > heap_d2[m]) m = r;
        if (m == i) return;
        float d = heap_d2[i]; heap_d2[i] = heap_d2[m]; heap_d2[m] = d;
        vec3 p = heap_power[i]; heap_power[i] = heap_power[m]; heap_power[m] = p;
        i = m;
    }
}
#endif

void photon_visit(uint index, Photon p, float d2) {
    if (dot(photon_normal(p), est_normal) <= 0.0) return;
    if (est_k == 0) {
        est_sum += photon_power(p);
        return;
    }
#if PHOTON_HEAP
    if (heap_n < est_k) {  // sift up
        int i = heap_n++;
        while (i > 0 && heap_d2[(i - 1) / 2] < d2) {
            heap_d2[i] = heap_d2[(i - 1) / 2];
            heap_power[i] = heap_power[(i - 1) / 2];
            i = (i - 1) / 2;
        }
        heap_d2[i] = d2;
        heap_power[i] = photon_power(p);
    } else if (d2 < heap_d2[0]) {
        heap_d2[0] = d2;
        heap_power[0] = photon_power(p);
        heap_sift_down(0);
    }
#endif
}

// Irradiance at q (scene-local) on the side n faces, radius r, estimator as above, heap size k.
vec3 photon_irradiance(vec3 q, vec3 n, float r, int estimator, int k) {
    est_r2 = r * r;
    est_normal = n;
    est_sum = vec3(0.0);
#if PHOTON_HEAP
    est_k = (estimator == PHOTON_ESTIMATOR_GRID_HEAP || estimator == PHOTON_ESTIMATOR_KDTREE_HEAP) ? clamp(k, 1, PHOTON_MAX_K) : 0;
    heap_n = 0;
#endif
#if PHOTON_KDTREE
    if (estimator >= PHOTON_ESTIMATOR_KDTREE) kdtree_search(q);
    else
#endif
    grid_search(q);
    float area_r2 = est_r2;
#if PHOTON_HEAP
    if (est_k > 0) {
        for (int i = 0; i < heap_n; ++i) est_sum += heap_power[i];
        if (heap_n == est_k) area_r2 = heap_d2[0];
    }
#endif
    return area_r2 > 0.0 ? est_sum / (PI * area_r2) : vec3(0.0);
}

#endif
