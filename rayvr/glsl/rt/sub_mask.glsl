// Coverage masks over a pixel's sub-rays (sub-ray i is bit i): which sub-rays hit a triangle, trace,
// or are the first on theirs (rt/primary.comp, rt/tile_samples.comp). One word up to 32 sub-rays,
// two beyond (shared channel shading at 16x casts 48), with the bit operations both need.
#ifndef RAYVR_RT_SUB_MASK_GLSL
#define RAYVR_RT_SUB_MASK_GLSL
#include "../common/camera.glsl"  // CAMERA_SUBRAYS

// MASK_WORDS: the words a mask takes in a uint array (bit k in word k / 32), MASK_OF_WORDS(w, i) the
// mask whose words start at w[i], MASK_ALL every sub-ray's.
#if CAMERA_SUBRAYS > 32
#define SubMask uvec2
#define MASK_WORDS 2u
#define MASK_NONE uvec2(0u)
#define MASK_BIT(k) ((k) < 32u ? uvec2(1u << (k), 0u) : uvec2(0u, 1u << ((k) - 32u)))
#define MASK_OF_WORDS(w, i) uvec2(w[i], w[(i) + 1u])
#define MASK_ALL uvec2(0xFFFFFFFFu, 0xFFFFFFFFu >> (64 - CAMERA_SUBRAYS))
#else
#define SubMask uint
#define MASK_WORDS 1u
#define MASK_NONE 0u
#define MASK_BIT(k) (1u << (k))
#define MASK_OF_WORDS(w, i) w[i]
#define MASK_ALL (0xFFFFFFFFu >> (32 - CAMERA_SUBRAYS))
#endif
uint mask_count(uint m) { return uint(bitCount(m)); }
uint mask_count(uvec2 m) { return uint(bitCount(m.x) + bitCount(m.y)); }
uint mask_lsb(uint m) { return uint(findLSB(m)); }
uint mask_lsb(uvec2 m) { return m.x != 0u ? uint(findLSB(m.x)) : 32u + uint(findLSB(m.y)); }
uint mask_drop_lsb(uint m) { return m & (m - 1u); }
uvec2 mask_drop_lsb(uvec2 m) { return m.x != 0u ? uvec2(m.x & (m.x - 1u), m.y) : uvec2(0u, m.y & (m.y - 1u)); }
bool mask_empty(uint m) { return m == 0u; }
bool mask_empty(uvec2 m) { return (m.x | m.y) == 0u; }
bool mask_same(uint a, uint b) { return a == b; }
bool mask_same(uvec2 a, uvec2 b) { return all(equal(a, b)); }
// The bits of m below bit k.
uint mask_count_below(uint m, uint k) { return k >= 32u ? uint(bitCount(m)) : uint(bitCount(m & ((1u << k) - 1u))); }
uint mask_count_below(uvec2 m, uint k) {
    return k < 32u ? mask_count_below(m.x, k) : uint(bitCount(m.x)) + mask_count_below(m.y, k - 32u);
}
#endif
