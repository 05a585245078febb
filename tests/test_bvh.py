"""BVH build invariants, refit, packing, limits, and the numpy reference traversal vs brute force."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.accel.bvh import (EMPTY_HI, EMPTY_LO, BufferTooLargeError, build_bvh, offset_ray,
                             trace_brute_force, trace_reference, widen)

MISS = 0xFFFFFFFF


def soup(n=300, seed=0, spread=10.0, size=1.0):
    """Random triangles: n independent triangles in a cube of side `spread`."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-spread / 2, spread / 2, (n, 1, 3))
    verts = (centers + rng.normal(scale=size, size=(n, 3, 3))).reshape(-1, 3)
    return verts.astype(np.float32), np.arange(3 * n).reshape(n, 3)


def random_rays(n, verts, seed=1):
    """Rays from a sphere around the mesh towards points near its centre (about half hit)."""
    rng = np.random.default_rng(seed)
    lo, hi = verts.min(0), verts.max(0)
    c, r = (lo + hi) / 2, np.linalg.norm(hi - lo)
    o = c + rng.normal(size=(n, 3)) * r
    d = c + rng.normal(size=(n, 3)) * r * 0.2 - o
    return o, d


def check_invariants(bvh, verts, faces):
    leaves = np.flatnonzero(bvh.left < 0)
    cover = np.zeros(bvh.triangle_count, int)
    for s, c in zip(bvh.start[leaves], bvh.count[leaves]):
        cover[s:s + c] += 1
    assert (cover == 1).all(), "every reordered triangle slot must be in exactly one leaf"
    assert np.array_equal(np.sort(bvh.prim_ids), np.arange(len(faces))), "prim_ids must be a permutation"
    tri = np.asarray(verts, np.float32)[np.asarray(faces)[bvh.prim_ids]]
    assert np.array_equal(bvh.triangles(), tri)
    for n in leaves:   # leaf boxes contain their triangles
        t = tri[bvh.start[n]:bvh.start[n] + bvh.count[n]].reshape(-1, 3)
        assert (bvh.node_lo[n] <= t.min(0)).all() and (t.max(0) <= bvh.node_hi[n]).all()
    inner = np.flatnonzero(bvh.left >= 0)
    for child in (bvh.left[inner], bvh.right[inner]):   # parents contain children, one level deeper
        assert (bvh.node_lo[inner] <= bvh.node_lo[child]).all()
        assert (bvh.node_hi[child] <= bvh.node_hi[inner]).all()
        assert (bvh.depth[child] == bvh.depth[inner] + 1).all()
    # Preorder: left child right after its parent; every node but the root has one parent.
    assert (bvh.left[inner] == inner + 1).all()
    parents = np.bincount(np.concatenate([bvh.left[inner], bvh.right[inner]]), minlength=bvh.node_count)
    assert parents[0] == 0 and (parents[1:] == 1).all()


@pytest.fixture(scope="module")
def bunny(request):
    from conftest import SHARED_SCENES
    p = SHARED_SCENES / "stanford_bunny" / "bun_zipper_res2.ply"
    if not p.exists():
        pytest.skip(f"{p} not found: the shared scenes folder is absent")
    import trimesh
    m = trimesh.load(p, force="mesh")
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces)


def test_invariants_soup():
    v, f = soup(500)
    bvh = build_bvh(v, f)
    check_invariants(bvh, v, f)
    assert bvh.count[bvh.left < 0].max() <= 8


def test_invariants_bunny(bunny):
    v, f = bunny
    bvh = build_bvh(v, f)
    check_invariants(bvh, v, f)
    s = bvh.stats()
    assert s["triangles"] == len(f) and 1.0 < s["sah_cost"] < 100.0 and s["max_depth"] <= 64


def test_sah_beats_a_bad_split():
    # One cluster of tiny triangles plus a few far ones: the SAH tree must be cheaper than a tree
    # that is forced to split by position only (bins=2 on a shuffled soup approximates a bad split).
    v, f = soup(400, size=0.05)
    good = build_bvh(v, f)
    coarse = build_bvh(v, f, bins=2)
    assert good.sah_cost() <= coarse.sah_cost()


def test_refit_keeps_boxes_and_hits():
    v, f = soup(300)
    bvh = build_bvh(v, f)
    rng = np.random.default_rng(3)
    moved = (v + rng.normal(scale=0.5, size=v.shape)).astype(np.float32)
    bvh.refit(moved)
    check_invariants(bvh, moved, f)
    o, d = random_rays(500, moved)
    ref = trace_reference(bvh, o, d)
    bf = trace_brute_force(moved, f, o, d)
    assert np.array_equal(ref[0], bf[0])
    with pytest.raises(ValueError, match="refit needs"):
        bvh.refit(moved[:-3])


def test_reference_matches_brute_force():
    v, f = soup(300, seed=5)
    bvh = build_bvh(v, f)
    o, d = random_rays(2000, v, seed=6)
    prim, t, u, w = trace_reference(bvh, o, d)
    bprim, bt, bu, bw = trace_brute_force(v, f, o, d)
    assert 0.2 < (prim != MISS).mean() < 0.9
    assert np.array_equal(prim, bprim)
    hit = prim != MISS
    assert np.array_equal(t[hit], bt[hit]) and np.array_equal(u[hit], bu[hit])
    # any hit with a finite segment
    occ = trace_reference(bvh, o, d, tmax=0.9, any_hit=True)
    assert np.array_equal(occ, trace_brute_force(v, f, o, d, tmax=0.9, any_hit=True))
    # barycentrics reproduce the hit point
    tri = v[f[prim[hit]]].astype(np.float64)
    p = (1 - u[hit] - w[hit])[:, None] * tri[:, 0] + u[hit][:, None] * tri[:, 1] + w[hit][:, None] * tri[:, 2]
    assert np.allclose(p, o[hit] + t[hit][:, None] * d[hit], atol=1e-6)


def test_depth_cap_and_coincident_centroids():
    # Geometrically spaced triangles make SAH trees deep; a cap must hold and traversal stay exact.
    x = 2.0 ** -np.arange(60, dtype=np.float64)
    tri = np.stack([np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1),
                    np.stack([x, np.ones_like(x), np.zeros_like(x)], 1),
                    np.stack([x, np.zeros_like(x), np.ones_like(x)], 1)], 1)
    v, f = tri.reshape(-1, 3).astype(np.float32), np.arange(180).reshape(60, 3)
    bvh = build_bvh(v, f, max_depth=6)
    assert bvh.max_depth <= 6
    check_invariants(bvh, v, f)
    # 50 copies of one triangle: no SAH split exists, the node is halved instead.
    one = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    v2, f2 = np.tile(one, (50, 1)), np.arange(150).reshape(50, 3)
    b2 = build_bvh(v2, f2)
    check_invariants(b2, v2, f2)
    assert b2.count[b2.left < 0].max() <= 8
    prim, t, _, _ = trace_reference(b2, [[0.2, 0.2, 1]], [[0, 0, -1]])
    assert prim[0] < 50 and t[0] == pytest.approx(1.0)


def test_empty_single_and_degenerate():
    empty = build_bvh(np.zeros((0, 3)), np.zeros((0, 3), int))
    assert empty.triangle_count == 0
    prim, t, _, _ = trace_reference(empty, [[0, 0, 0]], [[0, 0, 1]])
    assert prim[0] == MISS and np.isinf(t[0])
    nodes = empty.pack_nodes()
    assert nodes.shape == (1, 16) and (nodes[0, :6:2] <= EMPTY_LO).all() and (nodes[0, 1:6:2] >= EMPTY_HI).all()
    assert (nodes[0, :6:2] > nodes[0, 1:6:2]).all()   # still inverted after widening

    one = build_bvh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), [[0, 1, 2]])
    prim, t, u, w = trace_reference(one, [[0.25, 0.5, 2]], [[0, 0, -1]])
    assert prim[0] == 0 and t[0] == pytest.approx(2.0) and (u[0], w[0]) == pytest.approx((0.25, 0.5))
    meta = one.pack_nodes()[0, 12:].view(np.int32)
    assert list(meta) == [0, 0, 1, 0]   # left = leaf of 1 triangle, right = empty

    # zero-area triangles (a point and a line) build fine and are never hit
    deg = build_bvh(np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [1, 1, 1]]), [[0, 1, 2], [0, 1, 3]])
    prim, *_ = trace_reference(deg, [[0.5, 0.5, 2], [0, 0, 1]], [[0, 0, -1], [0, 0, -1]])
    assert (prim == MISS).all()


def test_bad_input_is_rejected():
    v, f = soup(10)
    bad = v.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match="NaN or inf.*first bad vertex: 7"):
        build_bvh(bad, f)
    bad[7, 1] = np.inf
    with pytest.raises(ValueError, match="NaN or inf"):
        build_bvh(bad, f)
    with pytest.raises(ValueError, match=r"indices must lie in \[0, 30\)"):
        build_bvh(v, f + 1)
    with pytest.raises(ValueError, match="shape"):
        build_bvh(v[:, :2], f)
    with pytest.raises(ValueError, match="shape"):
        build_bvh(v, f.reshape(-1, 6))


def test_buffer_limit_error_names_buffer():
    v, f = soup(100, seed=0)
    bvh = build_bvh(v, f)
    sizes = bvh.gpu_sizes()
    assert sizes["bvh_triangles"] == 100 * 48 and sizes["bvh_nodes"] == 64 * bvh.gpu_node_count
    bvh.check_fits(10 ** 9)   # fits
    # 100 copies of a triangle: few large leaves, so the node buffer is the smaller one.
    same = build_bvh(np.tile(v[:3], (100, 1)), np.arange(300).reshape(100, 3))
    with pytest.raises(BufferTooLargeError) as e:
        same.check_fits(same.gpu_sizes()["bvh_nodes"])     # nodes fit exactly, triangles do not
    assert e.value.buffer == "bvh_triangles" and e.value.size == 4800
    with pytest.raises(BufferTooLargeError) as e:
        bvh.check_fits(1000)
    assert isinstance(e.value, ValueError)
    msg = str(e.value)
    assert e.value.buffer in msg and f"{e.value.size:,}" in msg and "1,000" in msg
    assert e.value.size == sizes[e.value.buffer]


def test_packing_layout():
    v, f = soup(200)
    bvh = build_bvh(v, f)
    nodes, tris = bvh.pack_nodes(), bvh.pack_triangles()
    inner = np.flatnonzero(bvh.left >= 0)
    assert nodes.shape == (len(inner), 16) and tris.shape == (200, 12)
    assert np.array_equal(tris[:, 3].view(np.uint32), bvh.prim_ids)
    assert np.array_equal(tris.reshape(-1, 3, 4)[:, :, :3], bvh.triangles())
    # Root's children boxes and links
    meta = nodes[:, 12:].view(np.int32)
    l, r = bvh.left[0], bvh.right[0]
    assert np.array_equal(nodes[0, [0, 2, 4]], widen(bvh.node_lo[l], bvh.node_hi[l])[0])
    assert np.array_equal(nodes[0, [7, 9, 11]], widen(bvh.node_lo[r], bvh.node_hi[r])[1])
    gpu_index = {n: i for i, n in enumerate(inner)}
    for side, child in enumerate((l, r)):
        if bvh.left[child] < 0:
            assert (meta[0, side], meta[0, 2 + side]) == (bvh.start[child], bvh.count[child])
        else:
            assert (meta[0, side], meta[0, 2 + side]) == (gpu_index[child], 0)
    # Every triangle reachable from exactly one leaf slot across all GPU nodes
    leaf_counts = np.concatenate([meta[:, 2], meta[:, 3]])
    assert leaf_counts.sum() == 200


@pytest.mark.parametrize("shift", [0.0, 1e-3, 1.0, 1e5, -1e5])
def test_offset_ray_moves_to_the_normal_side(shift):
    rng = np.random.default_rng(2)
    p = (rng.uniform(-1, 1, (1000, 3)) * max(abs(shift), 1e-3) + shift).astype(np.float32)
    n = rng.normal(size=(1000, 3))
    n = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    q = offset_ray(p, n)
    assert np.isfinite(q).all()
    step = (q.astype(np.float64) - p) * n      # per axis: never against the normal
    assert (step >= 0).all()
    assert ((step.sum(1)) > 0).all()            # and strictly off the surface plane through p


def test_sah_cost_of_a_known_tree_is_its_closed_form():
    """Two unit triangles 10 apart in the z = 0 plane: the build must split them (one leaf each
    costs (1 + 1) / 11 + 1 against 2), and the cost is each node's box area over the root's
    (flat boxes: area dx * dy) times its test cost, written out by hand."""
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    verts = np.concatenate([tri, tri + np.float32([10, 0, 0])])
    bvh = build_bvh(verts, np.array([[0, 1, 2], [3, 4, 5]]))
    assert bvh.node_count == 3 and sorted(bvh.count[bvh.left < 0].tolist()) == [1, 1]
    root, leaf = 11.0 * 1.0, 1.0 * 1.0
    assert bvh.sah_cost() == pytest.approx((root + 2 * leaf) / root)
    assert bvh.sah_cost(traversal_cost=2.0, triangle_cost=3.0) == pytest.approx((2 * root + 3 * 2 * leaf) / root)


def hand_tree(left, right, leaf_triangles):
    """A Bvh built by hand: nodes in preorder with children `left`, `right` (-1: a leaf), the
    triangles (3 x 3 vertices each) of leaf n in `leaf_triangles[n]`, reordered into one range per
    leaf; boxes from `refit` (bottom up from the triangles)."""
    from rayvr.accel.bvh import Bvh

    n = len(left)
    start, count, depth = np.zeros(n, np.int32), np.zeros(n, np.int32), np.zeros(n, np.int32)
    tris = []
    for node in range(n):
        for child in (left[node], right[node]):
            if child >= 0:
                depth[child] = depth[node] + 1
        if left[node] < 0:
            start[node], count[node] = len(tris), len(leaf_triangles[node])
            tris += leaf_triangles[node]
    verts = np.asarray(tris, np.float32).reshape(-1, 3)
    bvh = Bvh(np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), np.asarray(left, np.int32),
              np.asarray(right, np.int32), start, count, depth, np.arange(len(tris), dtype=np.uint32),
              np.arange(len(verts)).reshape(-1, 3), verts)
    bvh.refit(verts)
    return bvh


def test_sah_cost_of_a_hand_built_three_level_tree_is_its_hand_computed_value():
    """A root over an internal node A (leaves A1 of two triangles and A2 of one) and a leaf B of
    three, boxes of three different sides each (so every term of the half area counts, and leaf
    sizes differ). Half areas xy + yz + zx by hand: root [0,4]x[0,2]x[0,1] 8 + 2 + 4 = 14, A
    [0,1]^3 3, A1 [0,1]x[0,1]x[0,.5] 1 + .5 + .5 = 2, A2 [0,1]x[0,1]x[.5,1] 2, B [2,4]x[0,2]x[0,1]
    4 + 2 + 2 = 8. SAH = (C_t (14 + 3) + C_i (2 x 2 + 2 x 1 + 8 x 3)) / 14. Fails if leaves are not
    weighted by their triangle counts (the two-leaf test's leaves hold one each), if a term of the
    half area is dropped (its boxes are flat), if leaves count as traversal steps, if the root's
    own test is left out or the sum is not over the root's area."""
    a1 = [[(0, 0, 0), (1, 0, 0), (0, 1, 0.5)], [(1, 1, 0.5), (1, 0, 0), (0, 1, 0)]]
    a2 = [[(0, 0, 0.5), (1, 1, 1), (1, 0, 0.75)]]
    b = [[(2, 0, 0), (4, 2, 1), (3, 1, 0.5)], [(2, 2, 1), (4, 0, 0), (3, 1, 0.5)], [(2, 0, 1), (4, 2, 0), (3, 0, 0)]]
    #              root A  A1  A2  B
    bvh = hand_tree([1, 2, -1, -1, -1], [4, 3, -1, -1, -1], {2: a1, 3: a2, 4: b})
    boxes = {0: ((0, 0, 0), (4, 2, 1)), 1: ((0, 0, 0), (1, 1, 1)), 2: ((0, 0, 0), (1, 1, 0.5)),
             3: ((0, 0, 0.5), (1, 1, 1)), 4: ((2, 0, 0), (4, 2, 1))}
    for node, (lo, hi) in boxes.items():
        assert bvh.node_lo[node].tolist() == list(lo) and bvh.node_hi[node].tolist() == list(hi)
    assert bvh.sah_cost() == pytest.approx((17 + 30) / 14, rel=1e-12)
    assert bvh.sah_cost(traversal_cost=2.0, triangle_cost=3.0) == pytest.approx((2 * 17 + 3 * 30) / 14, rel=1e-12)
