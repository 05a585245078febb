// The entry cut of a beam (HVVR's entry-point search): accel/tile_cull.comp for a frame tile,
// accel/block_cull.comp for a block of tiles. From a start list of binary BVH children (parent << 1
// | side) whose boxes meet the beam's frustum, sweep the list left to right opening internal entries
// into their children that meet the frustum while the list has room (CUT_ENTRIES); stop when a sweep
// opens nothing. Each sweep tests every entry's children at once (invocation k: entry k; their node
// fetches overlap), then invocation 0 builds the next list from those answers. Left-to-right order is
// kept, so entries stay in the start list's order; with TILE_SORT they end front to back along the
// beam's central direction c. Under the cut lies every triangle a ray of the beam can hit.
// The includer declares CUT_ENTRIES (at most its workgroup's invocations) and includes bvh.glsl and
// tile_frustum.glsl first.
#ifndef RAYVR_ACCEL_TILE_CUT_GLSL
#define RAYVR_ACCEL_TILE_CUT_GLSL

shared uint cut[2][CUT_ENTRIES];     // the list, and the next sweep's
shared uvec2 cut_children[CUT_ENTRIES];  // per entry: which children meet the frustum (4: a leaf), child node
shared float cut_key[CUT_ENTRIES];   // per entry: its box's nearest c.x (TILE_SORT)
shared int cut_count;
shared bool cut_opened;

// The start list: the root's children that meet the frustum (all of them for a beam not culled,
// which is then not opened either). Invocation 0 writes it; the caller's barrier follows.
void cut_start_at_root(vec4 planes[5], bool fallback) {
    int count = 0;
    for (int side = 0; side < 2; ++side) {
        vec3 lo, hi;
        bvh2_child_box(bvh_nodes[0], bvh_nodes[1], bvh_nodes[2], side, lo, hi);
        if (fallback || frustum_overlaps(planes, lo, hi))
            cut[0][count++] = uint(side);
    }
    cut_count = count;
    cut_opened = !fallback;
}

// The box of entry e (parent << 1 | side).
void cut_entry_box(uint e, out vec3 lo, out vec3 hi) {
    int parent = int(e >> 1u);
    bvh2_child_box(bvh_nodes[4 * parent], bvh_nodes[4 * parent + 1], bvh_nodes[4 * parent + 2], int(e & 1u), lo, hi);
}

// Open the start list in cut[0] (cut_count, cut_opened set, after a barrier) into the cut: on return
// (uniformly) cut[result][0 .. cut_count) holds it.
int beam_cut(uint lid, vec4 planes[5], vec3 c) {
    int cur = 0;
    // (cut_opened: dynamically uniform, shared, read after a barrier; BEAM_MAX_SWEEPS: a guard only)
    for (int sweep = 0; sweep < BEAM_MAX_SWEEPS && cut_opened; ++sweep) {
        int count = cut_count;
        if (lid < uint(count)) {
            uint e = cut[cur][lid];
            ivec4 m = floatBitsToInt(bvh_nodes[4 * int(e >> 1u) + 3]);
            bool left = (e & 1u) == 0u;
            int index = left ? m.x : m.y, cnt = left ? m.z : m.w;
            uint bits = 4u;          // a leaf: kept as it is
            if (cnt == 0) {
                bits = 0u;
                vec4 n0 = bvh_nodes[4 * index], n1 = bvh_nodes[4 * index + 1], n2 = bvh_nodes[4 * index + 2];
                for (int cs = 0; cs < 2; ++cs) {
                    vec3 lo, hi;
                    bvh2_child_box(n0, n1, n2, cs, lo, hi);
                    bits |= frustum_overlaps(planes, lo, hi) ? 1u << uint(cs) : 0u;
                }
            }
            cut_children[lid] = uvec2(bits, uint(index));
        }
        barrier();
        if (lid == 0u) {
            bool opened = false;
            int out_n = 0;
            for (int k = 0; k < count; ++k) {
                uvec2 ch = cut_children[k];
                // room: this entry's slot plus one more, and one slot for each entry still to copy
                if (ch.x == 4u || out_n + 2 + (count - k - 1) > CUT_ENTRIES) {
                    cut[1 - cur][out_n++] = cut[cur][k];
                    continue;
                }
                opened = true;
                for (uint cs = 0u; cs < 2u; ++cs)
                    if ((ch.x & (1u << cs)) != 0u)
                        cut[1 - cur][out_n++] = (ch.y << 1u) | cs;
            }
            cut_count = out_n;
            cut_opened = opened;
        }
        barrier();
        cur = 1 - cur;
    }
#if TILE_SORT
    // Front to back: by the entry box's nearest point along the central direction, min over the box
    // of c.x (keys at once, then a stable insertion sort; equal keys keep their order). A ray then
    // meets near entries first, its h.t shrinks early and farther entries fail their slab test, or
    // end its walk (bvh2.glsl bvh_traverse_entries). The hits cannot change: the leaf test's tie
    // rule (bvh.glsl bvh_test_triangle) makes them independent of the order.
    int count = cut_count;
    if (lid < uint(count)) {
        vec3 lo, hi;
        cut_entry_box(cut[cur][lid], lo, hi);
        cut_key[lid] = dot(c, 0.5 * (lo + hi)) - dot(abs(c), 0.5 * (hi - lo));
    }
    barrier();
    if (lid == 0u) {
        for (int k = 1; k < count; ++k) {
            uint e = cut[cur][k];
            float kk = cut_key[k];
            int j = k;
            for (; j > 0 && cut_key[j - 1] > kk; --j) {
                cut_key[j] = cut_key[j - 1];
                cut[cur][j] = cut[cur][j - 1];
            }
            cut_key[j] = kk;
            cut[cur][j] = e;
        }
    }
    barrier();
#endif
    return cur;
}
#endif
