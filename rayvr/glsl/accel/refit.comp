#version 430
// GPU refit of the binary BVH (rayvr/accel/refit.py) after its vertices moved, same topology:
// REFIT_STAGE 0: one invocation per reordered triangle slot rewrites its three vertices from the
//                vertex buffer (the id word is kept);
// REFIT_STAGE 1: one invocation per internal node of one tree level (deepest level first, one
//                dispatch each): each child box becomes the union of its leaf's triangles, or of the
//                two boxes stored in its child node (written by the previous dispatch), widened by
//                one ulp as bvh.widen does on the host. Boxes are written as bits, so the buffer
//                equals Bvh.pack_nodes() after a numpy refit, bit for bit.
#include "../layout.glsl"
layout(local_size_x = REFIT_LOCAL) in;  // rayvr/accel/refit.py dispatches by it
#ifndef BVH_NODES_BINDING
#define BVH_NODES_BINDING SSBO_BVH_NODES
#define BVH_TRIS_BINDING SSBO_BVH_TRIANGLES
#endif
#ifndef REFIT_STAGE
#define REFIT_STAGE 0
#endif

layout(std430, binding = BVH_NODES_BINDING) restrict buffer Nodes { uint nodes[]; };      // 16 words a node
layout(std430, binding = BVH_TRIS_BINDING) restrict buffer Tris { vec4 tris[]; };         // 3 vec4 a slot
layout(std430, binding = SSBO_REFIT_VERTICES) readonly restrict buffer Verts { vec4 verts[]; };
layout(std430, binding = SSBO_REFIT_INDEX) readonly restrict buffer Index { uint refit_index[]; };
// stage 0: 3 vertex indices per slot; stage 1: the GPU node numbers of every level, deepest first

uniform uint count;    // slots (stage 0) or nodes of this level (stage 1)
uniform uint offset;   // stage 1: this level's first entry in refit_index

uint invocation() { return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * REFIT_LOCAL; }

// nextafter towards -inf / +inf on the bits (bvh.widen); zero steps to the smallest denormal.
uint step_down(float x) {
    uint b = floatBitsToUint(x);
    return x > 0.0 ? b - 1u : (x < 0.0 ? b + 1u : 0x80000001u);
}
uint step_up(float x) {
    uint b = floatBitsToUint(x);
    return x > 0.0 ? b + 1u : (x < 0.0 ? b - 1u : 0x00000001u);
}

#if REFIT_STAGE == 0
void main() {
    uint i = invocation();
    if (i >= count) return;
    for (int k = 0; k < 3; ++k) {
        vec3 v = verts[refit_index[3u * i + uint(k)]].xyz;
        tris[3u * i + uint(k)] = vec4(v, k == 0 ? tris[3u * i].w : 0.0);
    }
}
#else
float node_word(uint n, int w) { return uintBitsToFloat(nodes[16u * n + uint(w)]); }

void main() {
    uint i = invocation();
    if (i >= count) return;
    uint g = refit_index[offset + i];
    for (int side = 0; side < 2; ++side) {
        uint index = nodes[16u * g + 12u + uint(side)];
        uint n = nodes[16u * g + 14u + uint(side)];
        vec3 lo = vec3(3.0e38), hi = vec3(-3.0e38);
        if (n > 0u) {                      // a leaf: its triangles
            for (uint t = index; t < index + n; ++t)
                for (uint k = 0u; k < 3u; ++k) {
                    vec3 v = tris[3u * t + k].xyz;
                    lo = min(lo, v);
                    hi = max(hi, v);
                }
        } else if (index > g) {            // an internal child (numbered after its parent): its two boxes
            for (int c = 0; c < 2; ++c) {
                int b = 6 * c;
                lo = min(lo, vec3(node_word(index, b), node_word(index, b + 2), node_word(index, b + 4)));
                hi = max(hi, vec3(node_word(index, b + 1), node_word(index, b + 3), node_word(index, b + 5)));
            }
            // the child's boxes are widened already, and widening commutes with min/max
            for (int a = 0; a < 3; ++a) {
                nodes[16u * g + uint(6 * side + 2 * a)] = floatBitsToUint(lo[a]);
                nodes[16u * g + uint(6 * side + 2 * a + 1)] = floatBitsToUint(hi[a]);
            }
            continue;
        } else {
            continue;                      // an empty slot (a lone leaf's partner): stays inverted
        }
        for (int a = 0; a < 3; ++a) {  // as bvh.widen: an ulp, and at least BVH_FACE_SLACK
            float l = min(uintBitsToFloat(step_down(lo[a])), lo[a] - BVH_FACE_SLACK);
            float h = max(uintBitsToFloat(step_up(hi[a])), hi[a] + BVH_FACE_SLACK);
            nodes[16u * g + uint(6 * side + 2 * a)] = floatBitsToUint(l);
            nodes[16u * g + uint(6 * side + 2 * a + 1)] = floatBitsToUint(h);
        }
    }
}
#endif
