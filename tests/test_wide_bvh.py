"""Wide BVH layouts (accel/wide.py, glsl/accel/bvh_wide.glsl) against the binary reference: the
numpy walks of both, the GPU traversals of every layout, and Embree."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.accel.bvh import build_bvh, trace_reference, widen
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer
from rayvr.accel.wide import build_wide, collapse, trace_wide_reference, unpack
from test_traversal_gpu import agreement, cube, cube_edge_rays, embree_closest, embree_scene, load_mesh, rays_at, soup


def test_collapse_keeps_every_leaf_once_and_fills_nodes():
    v, f = soup(1500, seed=2)
    bvh = build_bvh(v, f, max_leaf_size=2)
    for width in (4, 8):
        child = collapse(bvh, width)
        used = child[child >= 0]
        leaves = used[bvh.left[used] < 0]
        # every binary leaf exactly once: the same triangle ranges as the binary tree
        assert np.array_equal(np.sort(leaves), np.flatnonzero(bvh.left < 0))
        n = (child >= 0).sum(axis=1)
        assert n.min() >= 2 and n.max() == width
        # a node is left underfull only when none of its children can be opened (all leaves)
        under = child[n < width]
        assert (bvh.left[under[under >= 0]] < 0).all()
        # each internal child is a later node (BFS), each node but the root has one parent
        internal = used[bvh.left[used] >= 0]
        assert len(internal) == len(child) - 1
        assert build_wide(bvh, width).stats()["depth"] < bvh.max_depth


@pytest.mark.parametrize("offset,scale", [(0.0, 1.0), (1e5, 1.0), (0.0, 1e-3), (-3e4, 40.0)])
def test_quantized_boxes_contain_the_binary_boxes(offset, scale):
    v, f = soup(800, seed=5)
    v = (v * scale + offset).astype(np.float32)
    bvh = build_bvh(v, f)
    for width in (4, 8):
        w = build_wide(bvh, width)
        lo, hi = w.decode()
        valid = w.child >= 0
        blo, bhi = widen(bvh.node_lo[w.child[valid]], bvh.node_hi[w.child[valid]])
        assert (lo[valid] <= blo).all() and (hi[valid] >= bhi).all()
        # and stay tight: at most one quantum wider per side (+ an ulp), the quantum at most
        # 2/255 of the node's extent (a power of two at or above extent/255)
        _, ebias, _, _, _, _ = unpack(w.packed, width)
        quantum = np.ldexp(1.0, ebias - 127)
        q = np.broadcast_to(quantum[:, None, :], lo.shape)[valid]
        assert ((blo - lo[valid]) <= q * 1.0001).all() and ((hi[valid] - bhi) <= q * 1.0001).all()
        wlo, whi = widen(bvh.node_lo[w.child], bvh.node_hi[w.child])
        node_ext = (np.where(valid[..., None], whi, -np.inf).max(1)
                    - np.where(valid[..., None], wlo, np.inf).min(1)).astype(np.float64)
        assert (quantum <= np.maximum(node_ext * 2 / 255, 2.0 ** -126) * 1.0001).all()
        assert np.isfinite(lo[valid]).all() and np.isfinite(hi[valid]).all()


def test_collapse_opens_the_largest_child_and_keeps_the_binary_left_to_right_order():
    """A hand-built binary tree (preorder): root (1, 6), 1 (2, 5), 2 (3, 4), 6 (7, 8), leaves of one
    unit triangle each, box x ranges 3 [0,1], 4 [1,2], 5 [2,3], 7 [10,11] and 8 at 20 (far) or
    10.5 (near), y and z [0,1]. Half areas by hand: node 2 5, node 1 7, node 6 23 (far) or 4 (near).
    Width 4, far: the root's children 1, 6; 6 is larger, opened: 1, 7, 8; then 1: 2, 5, 7, 8 in the
    tree's left-to-right order, and a second node for 2: 3, 4. Near: 1 is opened first (7 > 4),
    then 2 (5 > 4): 3, 4, 5, 6, and 6's node 7, 8. Width 8 opens every internal node: one node of
    all five leaves. Fails if the smallest child is opened, or the first, or if the opened
    children are not put back in the tree's order; the packed slots follow the same order."""
    from test_bvh import hand_tree

    def unit(x):
        return [[(x, 0, 0), (x + 1, 1, 0), (x, 0, 1)]]

    left, right = [1, 2, 3, -1, -1, -1, 7, -1, -1], [6, 5, 4, -1, -1, -1, 8, -1, -1]
    for x8, area6, expected in ((20.0, 23.0, [[2, 5, 7, 8], [3, 4, -1, -1]]),
                                (10.5, 4.0, [[3, 4, 5, 6], [7, 8, -1, -1]])):
        bvh = hand_tree(left, right, {3: unit(0), 4: unit(1), 5: unit(2), 7: unit(10), 8: unit(x8)})
        side = (bvh.node_hi - bvh.node_lo).astype(np.float64)
        area = {n: side[n, 0] * side[n, 1] + side[n, 1] * side[n, 2] + side[n, 2] * side[n, 0] for n in (1, 2, 6)}
        assert area == {1: 7.0, 2: 5.0, 6: area6}
        assert collapse(bvh, 4).tolist() == expected
        assert collapse(bvh, 8).tolist() == [[3, 4, 5, 7, 8, -1, -1, -1]]
        w = build_wide(bvh, 4)
        _, _, nchild, _, count, index = unpack(w.packed, 4)
        lo, hi = w.decode()
        for node, row in enumerate(expected):
            kids = [c for c in row if c >= 0]
            assert nchild[node] == len(kids)
            for slot, c in enumerate(kids):
                leaf = bvh.left[c] < 0
                assert count[node, slot] == (1 if leaf else 0)
                assert index[node, slot] == (bvh.start[c] if leaf else 1)    # the internal child: wide node 1
                assert (lo[node, slot] <= bvh.node_lo[c]).all() and (hi[node, slot] >= bvh.node_hi[c]).all()


@pytest.mark.parametrize("width", [4, 8])
def test_numpy_wide_walk_matches_binary_reference(width):
    v, f = soup(1500, seed=1)
    bvh = build_bvh(v, f)
    w = build_wide(bvh, width)
    o, d = rays_at(v, 3000, seed=3)
    prim, t, _, _ = trace_reference(bvh, o, d)
    stats = {}
    wp, wt, _, _ = trace_wide_reference(w, o, d, stats=stats)
    assert 0.3 < (prim != MISS).mean() < 0.95
    assert np.array_equal(wp, prim) and np.array_equal(wt, t)   # same float64 triangle tests
    ref_stats = {}
    trace_reference(bvh, o, d, stats=ref_stats)
    assert stats["node_visits"].mean() < ref_stats["pair_node_visits"].mean()   # fewer node fetches
    occ = trace_wide_reference(w, o, d, tmax=0.6, any_hit=True)
    assert np.array_equal(occ, trace_reference(bvh, o, d, tmax=0.6, any_hit=True))


def gpu_traces(gl, bvh, o, d, **kw):
    out = {}
    for layout in ("bvh2", "bvh4", "bvh8"):
        gb = GpuBvh(gl, bvh, layout=layout)
        for ordered in ((True, False) if layout != "bvh2" else (True,)):
            rt = RayTracer(gl, gb, ordered=ordered)
            out[layout, ordered] = (rt.trace(o, d, **kw), rt.trace(o, d, tmax=kw.get("tmax", np.inf) * 0.5,
                                                                    mode="any"))
        gb.release()
    return out


def assert_same_as_binary(out, prim_ref=None, t_ref=None):
    base, base_any = out["bvh2", True]
    for key, (h, occ) in out.items():
        # The same float32 triangle test on the same triangles: identical hits, bit for bit, except
        # where two triangles tie at the same t (an edge), which traversal order decides.
        frac, err = agreement(h.prim, h.t, base.prim, base.t, rel=0.0)
        assert frac == 1.0 and err == 0.0, f"{key}: {frac:.4%} agree with bvh2"
        assert np.array_equal(occ, base_any), f"{key}: any-hit differs from bvh2"
        if prim_ref is not None:
            frac, err = agreement(h.prim, h.t, prim_ref, t_ref)
            assert frac >= 0.999 and err <= 1e-5


def test_gpu_layouts_match_binary_on_soup(gl):
    v, f = soup(2000, seed=6)
    bvh = build_bvh(v, f)
    o, d = rays_at(v, 3000, seed=9)
    prim, t, _, _ = trace_reference(bvh, o, d)
    assert_same_as_binary(gpu_traces(gl, bvh, o, d, tmax=np.float32(40.0)), prim, t)


def test_gpu_layouts_axis_rays_edges_and_degenerate(gl):
    v, f = cube()
    o, d, inside = cube_edge_rays()
    bvh = build_bvh(v, f, max_leaf_size=1)
    out = gpu_traces(gl, bvh, o, d, tmax=np.float32(100.0))
    assert_same_as_binary(out)
    h = out["bvh8", True][0]
    assert (h.prim[:len(inside)][inside] != MISS).all() and np.allclose(h.t[:len(inside)][inside], 4.0)
    assert h.prim[-4] != MISS and (h.prim[-3:] == MISS).all()


def test_gpu_layouts_empty_and_single_triangle(gl):
    o = np.array([[0.2, 0.2, -1], [5, 5, -1]], np.float32)
    d = np.array([[0, 0, 1], [0, 0, 1]], np.float32)
    one = build_bvh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
    empty = build_bvh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    for layout in ("bvh4", "bvh8"):
        h = RayTracer(gl, GpuBvh(gl, one, layout=layout)).trace(o, d)
        assert h.prim.tolist() == [0, MISS] and h.t[0] == pytest.approx(1.0)
        h = RayTracer(gl, GpuBvh(gl, empty, layout=layout)).trace(o, d)
        assert (h.prim == MISS).all()
        assert not trace_wide_reference(build_wide(empty, 4 if layout == "bvh4" else 8), o, d, any_hit=True).any()


def test_gpu_wide_refit_update(gl):
    v, f = soup(600, seed=3)
    bvh = build_bvh(v, f)
    gb = GpuBvh(gl, bvh, layout="bvh4")
    rt = RayTracer(gl, gb)
    moved = (v * 1.3 + np.sin(v[:, [1, 2, 0]])).astype(np.float32)
    bvh.refit(moved)
    gb.update()
    o, d = rays_at(moved, 2000, seed=4)
    fresh = RayTracer(gl, GpuBvh(gl, build_bvh(moved, f), layout="bvh4")).trace(o, d)
    h = rt.trace(o, d)
    frac, err = agreement(h.prim, h.t, fresh.prim, fresh.t, rel=0.0)
    assert frac == 1.0 and err == 0.0


def test_unknown_layout_and_deep_stack_are_clear_errors(gl, monkeypatch):
    v, f = soup(200)
    with pytest.raises(ValueError, match="bvh2, bvh4, bvh8"):
        GpuBvh(gl, build_bvh(v, f), layout="bvh16")
    from rayvr.accel import gpu
    monkeypatch.setitem(gpu.WIDE_STACK_SIZES, 8, 2)   # a tree whose worst case exceeds the GPU stack
    with pytest.raises(ValueError, match="bvh8: a traversal may hold .* stack entries, more than the GPU stack"):
        GpuBvh(gl, build_bvh(v, f), layout="bvh8")


def test_wide_layouts_match_embree_in_sponza(gl):
    v, f = load_mesh("sponza_dabrovic/sponza.obj")
    scene = embree_scene(v, f)
    bvh = build_bvh(v, f)
    rng = np.random.default_rng(7)
    lo, hi = v.min(0), v.max(0)
    o = rng.uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), (3000, 3)).astype(np.float32)
    d = rng.normal(size=(3000, 3)).astype(np.float32)
    eprim, et = embree_closest(scene, o, d / np.linalg.norm(d, axis=1, keepdims=True))
    for layout in ("bvh4", "bvh8"):
        h = RayTracer(gl, GpuBvh(gl, bvh, layout=layout)).trace(o, d / np.linalg.norm(d, axis=1, keepdims=True))
        frac, err = agreement(h.prim, h.t, eprim, et)
        assert frac >= 0.999 and err <= 1e-5, f"{layout}: {frac:.4%} agree with Embree"


@pytest.mark.parametrize("traversal", [("bvh8", "bvh4", "bvh8"), "bvh4"])
def test_renderer_traversal_per_ray_kind_gives_the_reference_frame(gl, traversal):
    """Primary rays, shadow rays and mirror/glossy rays each through a wide layout: the same frame
    as the binary reference (same triangles hit, so the same shading)."""
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene.materials import parse_config
    from rayvr.renderer import Renderer, RenderSettings
    from rayvr.scene.loader import load
    from test_raytrace import render
    scene = load()
    rig = StereoRig.for_scene(scene, size=(40, 30))
    cfg = {"default": "shadows", "materials": {"floor": {"effect": "glossy", "samples": 2},
                                               "mirror*": {"effect": "reflections", "bounces": 2}}}
    ref, ref_hdr, _ = render(gl, scene, rig, cfg, RenderSettings(primary="rays", traversal="bvh2"))
    # per-ray primaries (tile culling walks the binary layout, whatever the traversal names)
    r = Renderer(scene, parse_config(cfg, "test"), gl=gl,
                 settings=RenderSettings(primary="rays", traversal=traversal, tile_culling=False))
    try:
        wide = r.render(rig, aux=("triangle", "hdr"))
        hdr = np.stack([wide.left.aux["hdr"], wide.right.aux["hdr"]])
        passes = {p.name: p for p in r.compiled().passes}
        wanted = set(r.settings.traversal) - {"bvh2"}
        assert set(r.accel.wide) == wanted          # the wide node buffers were built and used
        assert passes["primary_rays"].layout == r.settings.traversal[0]
        assert passes["rt_reflections"].layouts["shadow"] == r.settings.traversal[1]
        assert passes["rt_glossy"].layouts["closest"] == r.settings.traversal[2]
    finally:
        r.release()
    assert "rt_shadows" in passes
    assert np.array_equal(wide.left.aux["triangle"], ref.left.aux["triangle"])
    assert np.array_equal(wide.right.aux["triangle"], ref.right.aux["triangle"])
    assert np.abs(hdr - ref_hdr).max() <= 1e-5 * max(1.0, float(ref_hdr.max()))
    with pytest.raises(ValueError, match="unknown ray kind 'secondary'"):
        RenderSettings(traversal="secondary=bvh4")


@pytest.mark.parametrize("x", [0.5, 0.0])
def test_a_tie_at_a_shared_edge_goes_to_the_lower_triangle_id(gl, x):
    """Rays down onto the edge two triangles share hit both at the same t. One triangle is folded
    up towards the rays, so its box is nearer and every traversal meets it first; before the tie
    rule that decided the hit (1 ray in 4.6 M on Sponza differed between tile-culled and per-ray
    traversal that way: bench/results/llvmpipe/tile_culling_tie). Every variant, and the numpy
    walks, report the lower ID, as the brute force's first minimum does. At x = 0 the rays lie in
    the folded triangle's box face at 0, which a one-ulp widening (a denormal) did not open."""
    from rayvr.accel.bvh import trace_brute_force

    v = np.array([[x, -1, 0], [x, 1, 0], [x + 1, 0, 0], [x - 1, 0, 1]], np.float32)
    for f in (np.array([[0, 1, 2], [0, 1, 3]]), np.array([[0, 1, 3], [0, 1, 2]])):  # flat first, then folded first
        y = np.linspace(-0.9, 0.9, 7, dtype=np.float32)
        o = np.stack([np.full_like(y, x), y, np.full_like(y, 5.0)], 1)
        d = np.tile(np.float32([0, 0, -1]), (len(y), 1))
        expected, t_ref, _, _ = trace_brute_force(v, f, o, d)
        assert (expected == 0).all() and np.allclose(t_ref, 5.0)
        bvh = build_bvh(v, f, max_leaf_size=1)
        prim, _, _, _ = trace_reference(bvh, o, d)
        assert np.array_equal(prim, expected), "numpy binary walk"
        for width in (4, 8):
            prim, _, _, _ = trace_wide_reference(build_wide(bvh, width), o, d)
            assert np.array_equal(prim, expected), f"numpy bvh{width} walk"
        for key, (h, _) in gpu_traces(gl, bvh, o, d, tmax=np.float32(100.0)).items():
            assert np.array_equal(h.prim, expected), f"GPU {key}"
        gb = GpuBvh(gl, bvh)
        assert np.array_equal(RayTracer(gl, gb).trace(o, d, tmax=np.float32(100.0), tiles=True).prim, expected)
        gb.release()
