"""Spatial splits (accel/sbvh.py): exact clipping, SAH quality, duplication budget, and traversal of the
duplicated references (numpy, every GPU layout, Embree, refit) against brute force."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.accel.bvh import SPATIAL_MIN_REFS, build_bvh, intersect_triangles, trace_brute_force, trace_reference
from rayvr.accel.sah import _half_area
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer
from rayvr.accel.refit import GpuRefit
from rayvr.accel.sbvh import _unsplit, clip_boxes
from rayvr.accel.wide import build_wide, trace_wide_reference
from test_traversal_gpu import embree_closest, embree_scene

TREE = ("node_lo", "node_hi", "left", "right", "count", "depth", "prim_ids", "indices")


def slivers(n=64, seed=0, width=0.01):
    """n long thin triangles along the cube's diagonal, slightly shifted: every box is ~ the cube."""
    rng = np.random.default_rng(seed)
    base = np.array([[0, 0, 0], [1, 1, 1], [width, 0, 0]], np.float64)
    return (base[None] + rng.uniform(-0.1, 0.1, (n, 1, 3))).reshape(-1, 3).astype(np.float32), \
        np.arange(3 * n).reshape(n, 3)


def thin_mesh(n=300, seed=3):
    """Long thin triangles in random directions (length ~2 in a box of 4) over a few small ones."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-2, 2, (n, 3))
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    side = np.cross(axis, rng.normal(size=(n, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    long = np.arange(n) < n * 3 // 4
    half = np.where(long, 1.0, 0.1)[:, None]
    v = np.stack([c - half * axis, c + half * axis, c + 0.04 * side], 1)
    return v.reshape(-1, 3).astype(np.float32), np.arange(3 * n).reshape(n, 3)


def rays_to_triangles(v, f, n, seed):
    """Half the rays aimed at random points on random triangles (thin ones are hit), half at random."""
    rng = np.random.default_rng(seed)
    tri = v[f].astype(np.float64)
    lo, hi = v.min(0), v.max(0)
    c, r = (lo + hi) / 2, np.linalg.norm(hi - lo)
    o = c + rng.normal(size=(n, 3)) * r
    k = rng.integers(0, len(f), n)
    a, b = rng.random((2, n, 1))
    a, b = np.where(a + b > 1, 1 - a, a), np.where(a + b > 1, 1 - b, b)
    target = tri[k, 0] + a * (tri[k, 1] - tri[k, 0]) + b * (tri[k, 2] - tri[k, 0])
    target[n // 2:] = c + rng.normal(size=(n - n // 2, 3)) * r * 0.3
    return o.astype(np.float32), (target - o).astype(np.float32)   # the rays the GPU traces


def assert_same_hits(prim, t, ref_prim, ref_t, tri=None, o=None, d=None, tol=1e-5):
    """Same triangle and distance (1e-5 relative) for every ray; a different triangle only as a tie
    (the room has coplanar overlapping quads, found in whatever order): with the rays and triangles
    `tri` given, that triangle must be hit at the reference's distance too."""
    assert np.array_equal(prim == MISS, ref_prim == MISS)
    hit = ref_prim != MISS
    assert (np.abs(t[hit] - ref_t[hit]) <= tol * np.maximum(1.0, ref_t[hit])).all()
    other = np.flatnonzero(prim != ref_prim)
    if len(other):
        assert tri is not None, f"{len(other)} rays hit another triangle"
        k = tri[prim[other]].astype(np.float64)
        h, tt, _, _ = intersect_triangles(o[other], d[other], k[:, 0], k[:, 1], k[:, 2], 0.0, np.inf)
        assert h.all() and np.allclose(tt, ref_t[other], rtol=max(tol, 1e-6), atol=0)


def test_clip_boxes_analytic_and_sampled():
    # right triangle (0,0,0) (2,0,0) (0,2,0) cut to 0.5 <= x <= 1: corners (.5,0) (1,0) (1,1) (.5,1.5)
    tri = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]]], np.float64)
    lo, hi = clip_boxes(tri, 0, np.array([0.5]), np.array([1.0]))
    assert np.allclose(lo, [[0.5, 0, 0]]) and np.allclose(hi, [[1.0, 1.5, 0]])
    lo, hi = clip_boxes(tri, 1, np.array([3.0]), np.array([4.0]))     # the slab misses it: empty
    assert (lo > hi).all()
    # random triangles and slabs: the box is that of a polygon clipper's result (Sutherland-Hodgman,
    # one triangle at a time) and holds every sampled point of the cut
    rng = np.random.default_rng(5)
    tri = rng.normal(size=(200, 3, 3))
    axis = 1
    a = rng.normal(size=200) * 0.5
    b = a + rng.uniform(0.05, 1.0, 200)
    lo, hi = clip_boxes(tri, axis, a, b)
    w = rng.dirichlet(np.ones(3), 4000)                                # barycentric samples
    pts = np.einsum("sk,tkc->tsc", w, tri)
    inside = (pts[..., axis] >= a[:, None]) & (pts[..., axis] <= b[:, None])
    for t in range(len(tri)):
        poly = clip_polygon(clip_polygon(list(tri[t]), axis, a[t], 1.0), axis, b[t], -1.0)
        if not poly:
            assert (lo[t] > hi[t]).all() and not inside[t].any()
            continue
        assert np.allclose(lo[t], np.min(poly, 0), rtol=0, atol=1e-12)
        assert np.allclose(hi[t], np.max(poly, 0), rtol=0, atol=1e-12)
        p = pts[t][inside[t]]
        assert (lo[t] <= p.min(0, initial=np.inf) + 1e-12).all() and (p.max(0, initial=-np.inf) <= hi[t] + 1e-12).all()


def clip_polygon(poly, axis, c, sign):
    """The part of a convex polygon (list of points) where sign * (x[axis] - c) >= 0."""
    out = []
    for p, q in zip(poly, poly[1:] + poly[:1]):
        dp, dq = sign * (p[axis] - c), sign * (q[axis] - c)
        if dp >= 0:
            out.append(p)
        if dp * dq < 0:
            out.append(p + (q - p) * (dp / (dp - dq)))
    return out


def test_reference_unsplitting_moves_a_barely_cut_reference_whole():
    # children [0,1] and [1,2] along x of a unit cube section, 10 references each (half areas 3 and 3)
    child = [np.array([[0.0, 0, 0]]), np.array([[1.0, 1, 1]]), np.array([[1.0, 0, 0]]), np.array([[2.0, 1, 1]])]
    counts = [np.array([10]), np.array([10])]
    side = lambda lo, hi: int(_unsplit(np.array([lo], float), np.array([hi], float), child, counts)[0])  # noqa: E731
    # [0.5, 1.01]: left grows to half area 3.03: 30.3 + 27 < 60 -> whole to the left
    assert side([0.5, 0, 0], [1.01, 1, 1]) == 0
    assert side([0.99, 0, 0], [1.5, 1, 1]) == 1
    # [0.2, 1.8]: either side grows to half area 4.6: 46 + 27 > 60 -> stays in both
    assert side([0.2, 0, 0], [1.8, 1, 1]) == 2


def test_spatial_splits_beat_the_object_split_bound_on_diagonal_slivers():
    v, f = slivers(64)
    tri = v[f].astype(np.float64)
    # Any BVH without spatial splits holds each triangle whole in one leaf whose box contains the
    # triangle's box: its SAH cost is at least the sum of the triangle boxes' areas over the root's.
    bound = _half_area(tri.min(1), tri.max(1)).sum() / _half_area(tri.min((0, 1)), tri.max((0, 1)))
    sah = build_bvh(v, f)
    assert sah.sah_cost() >= bound
    sbvh = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1)
    assert sbvh.sah_cost() < sah.sah_cost()
    assert len(f) < sbvh.reference_count <= 1.3 * len(f)              # the default budget: +30 %
    doubled = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, max_duplication=1.0)
    assert doubled.sah_cost() < bound                                   # beyond any object-split BVH
    assert doubled.reference_count <= 2 * len(f)
    assert build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, max_duplication=0.0).reference_count == len(f)


def test_every_point_of_every_triangle_lies_in_a_leaf_of_its_references():
    v, f = thin_mesh(120)
    bvh = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, max_duplication=1.0)
    assert bvh.reference_count > len(f) and bvh.triangle_count == len(f)
    assert np.array_equal(np.unique(bvh.prim_ids), np.arange(len(f)))
    assert np.array_equal(bvh.indices, f[bvh.prim_ids])                # each slot: the full triangle
    leaves = np.flatnonzero(bvh.left < 0)
    slot_leaf = np.repeat(leaves, bvh.count[leaves])[np.argsort(np.repeat(bvh.start[leaves], bvh.count[leaves]),
                                                                 kind="stable")]
    w = np.random.default_rng(6).dirichlet(np.ones(3), 300)
    for t in range(len(f)):
        pts = w @ v[f[t]].astype(np.float64)
        boxes = slot_leaf[bvh.prim_ids == t]
        lo, hi = bvh.node_lo[boxes], bvh.node_hi[boxes]
        held = ((pts[:, None] >= lo[None]) & (pts[:, None] <= hi[None])).all(-1).any(1)
        assert held.all(), f"triangle {t}: {int((~held).sum())} points outside its references' leaves"


def test_every_box_on_a_references_path_holds_its_float64_piece_split_planes_included(monkeypatch):
    """A spatial split cuts a triangle at a float64 plane: the pieces' boxes are float64 (corners
    where the edges cross the plane) and are stored as float32, rounded outwards, so every box from
    the root to a reference's leaf holds the whole float64 piece. Rounded to nearest, a box can end
    half an ulp short of a crossing point, and a ray there misses the triangle in every child. The
    crossing points of each triangle with every split plane of the build, and its vertices, must
    each lie in all the boxes on the path to one of its leaves (float64 compare, no tolerance
    beyond float64 rounding)."""
    from rayvr.accel import sbvh as sbvh_mod

    planes = set()  # (axis, plane) of every spatial split (the partition's cuts: one side unbounded)
    clip = sbvh_mod._clip_refs

    def recording(tri64, ref_lo, ref_hi, axis, lo, hi):
        if np.isinf(lo).all() or np.isinf(hi).all():
            planes.update((axis, float(c)) for c in np.unique(np.where(np.isinf(lo), hi, lo)))
        return clip(tri64, ref_lo, ref_hi, axis, lo, hi)

    monkeypatch.setattr(sbvh_mod, "_clip_refs", recording)
    v, f = thin_mesh(300)
    bvh = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, max_duplication=1.0)
    assert len(planes) > 20 and bvh.reference_count > len(f)
    parent = np.full(bvh.node_count, -1)
    inner = np.flatnonzero(bvh.left >= 0)
    parent[bvh.left[inner]], parent[bvh.right[inner]] = inner, inner
    leaves = np.flatnonzero(bvh.left < 0)
    slot_leaf = np.empty(bvh.reference_count, np.int64)
    for leaf in leaves:
        slot_leaf[bvh.start[leaf]:bvh.start[leaf] + bvh.count[leaf]] = leaf

    def path(node):
        out = []
        while node >= 0:
            out.append(node)
            node = parent[node]
        return np.array(out)

    paths = {leaf: path(leaf) for leaf in leaves}
    lo64, hi64 = bvh.node_lo.astype(np.float64), bvh.node_hi.astype(np.float64)
    tri = v[f].astype(np.float64)
    checked = 0
    for t in range(len(f)):
        pts = [tri[t]]
        for axis, c in planes:  # the edges' crossings of the plane, computed from either end
            for a, b in ((0, 1), (1, 2), (2, 0)):
                p, q = tri[t, a], tri[t, b]
                if (p[axis] - c) * (q[axis] - c) < 0:
                    pts.append([p + (q - p) * ((c - p[axis]) / (q[axis] - p[axis])),
                                q + (p - q) * ((c - q[axis]) / (p[axis] - q[axis]))])
        pts = np.concatenate([np.reshape(x, (-1, 3)) for x in pts])
        slack = 4 * np.finfo(np.float64).eps * np.abs(pts)  # the two float64 formulas differ in the last bits
        held = np.zeros(len(pts), bool)
        for slot in np.flatnonzero(bvh.prim_ids == t):
            nodes = paths[slot_leaf[slot]]
            inside = ((pts[:, None] >= lo64[nodes][None] - slack[:, None])
                      & (pts[:, None] <= hi64[nodes][None] + slack[:, None]))
            held |= inside.all(axis=(1, 2))
        assert held.all(), f"triangle {t}: {pts[~held][:2].tolist()} outside every path to its references"
        checked += len(pts) - 3
    assert checked > 2000  # crossing points on split planes were tested


def test_without_spatial_splits_the_reference_build_is_the_sah_tree():
    # the SBVH's per-level reference lists against the SAH build's in-place partition
    v, f = thin_mesh(300)
    a = build_bvh(v, f)
    b = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, split_alpha=1e30)
    assert all(np.array_equal(getattr(a, k), getattr(b, k)) for k in TREE)
    leaf = a.left < 0
    assert np.array_equal(a.start[leaf], b.start[leaf])


def test_spatial_splits_only_in_nodes_of_enough_references():
    # the default tries them in nodes of SPATIAL_MIN_REFS references or more; above the triangle
    # count, none is tried and the tree is the SAH build's
    v, f = thin_mesh(300)
    every = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1)
    some = build_bvh(v, f, spatial_splits=True, spatial_min_refs=64)
    none = build_bvh(v, f, spatial_splits=True, spatial_min_refs=len(f) + 1)
    assert every.params["spatial_split_nodes"] > some.params["spatial_split_nodes"] > 0
    assert none.params["spatial_split_nodes"] == 0 and none.reference_count == len(f)
    a = build_bvh(v, f)
    assert all(np.array_equal(getattr(a, k), getattr(none, k)) for k in TREE)
    assert build_bvh(v, f, spatial_splits=True).params["spatial_min_refs"] == SPATIAL_MIN_REFS


def test_bad_sbvh_parameters_are_rejected():
    v, f = slivers(4)
    with pytest.raises(ValueError, match="split_alpha"):
        build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, split_alpha=-1)
    with pytest.raises(ValueError, match="max_duplication"):
        build_bvh(v, f, spatial_splits=True, spatial_min_refs=1, max_duplication=float("nan"))
    with pytest.raises(ValueError, match="spatial_min_refs"):
        build_bvh(v, f, spatial_splits=True, spatial_min_refs=0)


@pytest.fixture(scope="module")
def meshes():
    """(name, vertices, faces, SBVH, SAH BVH, rays, brute-force closest hits) for the thin mesh and the room."""
    from rayvr.scene import loader as scene_mod
    room = scene_mod.load(None)
    out = []
    for name, (v, f), n in (("thin", thin_mesh(300), 1000), ("room", (room.vertices, room.indices), 400)):
        sbvh = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1)
        assert len(f) < sbvh.reference_count <= 1.3 * len(f), f"{name}: no spatial split, or over budget"
        o, d = rays_to_triangles(v, f, n, seed=7)
        out.append((name, v, f, sbvh, build_bvh(v, f), o, d, trace_brute_force(v, f, o, d)))
    return out


def test_numpy_traversals_return_the_brute_force_hits(meshes):
    for name, v, f, sbvh, sah, o, d, ref in meshes:
        assert 0.3 < (ref[0] != MISS).mean() < 0.98, name
        tri = v[f]
        prim, t, _, _ = trace_reference(sbvh, o, d)
        assert_same_hits(prim, t, ref[0], ref[1], tri, o, d)
        assert_same_hits(*trace_reference(sah, o, d)[:2], prim, t, tri, o, d)
        for width in (4, 8):
            assert_same_hits(*trace_wide_reference(build_wide(sbvh, width), o, d)[:2], ref[0], ref[1], tri, o, d)
        tmax = np.where(ref[0] != MISS, ref[1], 1.0) * np.random.default_rng(8).uniform(0.5, 1.5, len(o))
        occ = np.isfinite(trace_brute_force(v, f, o, d, tmax=tmax)[1])
        assert np.array_equal(trace_reference(sbvh, o, d, tmax=tmax, any_hit=True), occ)


def gpu_hits(gl, bvh, o, d, layout="bvh2", **kw):
    g = GpuBvh(gl, bvh, layout=layout)
    try:
        return RayTracer(gl, g).trace(o, d, **kw)
    finally:
        g.release()


def test_gpu_layouts_return_the_brute_force_hits(gl, meshes):
    # Against the SAH BVH's GPU hits: the same float32 triangle test, so the same t exactly; against
    # brute force (float64) to float32 accuracy (thin triangles: 1e-4 relative).
    for name, v, f, sbvh, sah, o, d, ref in meshes:
        base = gpu_hits(gl, sah, o, d)
        assert_same_hits(base.prim, base.t, ref[0], ref[1], v[f], o, d, tol=1e-4)
        tmax = np.where(ref[0] != MISS, ref[1], 1.0) * np.random.default_rng(9).uniform(0.5, 1.5, len(o))
        occ = np.isfinite(trace_brute_force(v, f, o, d, tmax=tmax)[1])
        for layout, tiles in (("bvh2", False), ("bvh2", True), ("bvh4", False), ("bvh8", False)):
            h = gpu_hits(gl, sbvh, o, d, layout, tiles=tiles)
            assert_same_hits(h.prim, h.t, base.prim, base.t, v[f], o, d, tol=0.0)
            if not tiles:
                assert np.array_equal(gpu_hits(gl, sbvh, o, d, layout, tmax=tmax, mode="any"), occ), (name, layout)


def test_sbvh_agrees_with_embree(meshes):
    name, v, f, sbvh, _, o, d, _ = meshes[0]
    prim, t = embree_closest(embree_scene(v, f), o, d)
    mine, tm, _, _ = trace_reference(sbvh, o, d)
    assert (mine == prim).mean() >= 0.999
    same = (mine == prim) & (prim != MISS)
    # Embree's t is float32 from its own triangle test: to float32 accuracy, as in the GPU layouts'
    # test against brute force (thin triangles: 1e-4 relative; one ray of a thousand was 1.1e-5 off)
    assert np.allclose(tm[same], t[same], rtol=1e-4)


def test_refit_of_duplicated_references_stays_conservative(gl):
    v, f = thin_mesh(200)
    moved = (v * 1.2 + 0.3 * np.sin(v[:, [1, 2, 0]] * 2.0)).astype(np.float32)
    o, d = rays_to_triangles(moved, f, 1000, seed=10)
    ref = trace_brute_force(moved, f, o, d)
    host = build_bvh(v, f, spatial_splits=True, spatial_min_refs=1)
    assert host.reference_count > len(f)
    host.refit(moved)
    assert_same_hits(*trace_reference(host, o, d)[:2], ref[0], ref[1])
    g = GpuBvh(gl, build_bvh(v, f, spatial_splits=True, spatial_min_refs=1))
    refit = GpuRefit(gl, g)
    try:
        refit.run(moved)
        assert np.array_equal(refit.read_nodes().view(np.uint32), host.pack_nodes().view(np.uint32))
        h = RayTracer(gl, g).trace(o, d)
        assert_same_hits(h.prim, h.t, ref[0], ref[1], moved[f], o, d, tol=1e-4)
        base = gpu_hits(gl, build_bvh(moved, f), o, d)               # a fresh build, same float32 test
        assert_same_hits(h.prim, h.t, base.prim, base.t, moved[f], o, d, tol=0.0)
    finally:
        refit.release()
        g.release()


def test_renderer_sbvh_frame_equals_the_sah_frame(gl):
    """--bvh-build sbvh through RenderSettings: ray-cast primary visibility, shadows and mirror rays hit
    the same scene triangles as on the SAH BVH (the G-buffer's triangle IDs are original IDs)."""
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene.materials import parse_config
    from rayvr.renderer import Renderer, RenderSettings
    from rayvr.scene.loader import load
    scene = load()
    rig = StereoRig.for_scene(scene, size=(32, 24))
    cfg = parse_config({"default": "shadows", "materials": {"mirror*": {"effect": "reflections", "bounces": 2}}},
                       "test")
    r = Renderer(scene, cfg, gl=gl, settings=RenderSettings(primary="rays", bvh_build="sbvh"))
    try:
        frames = {}
        for build in ("sbvh", "sah"):          # the second switches the build: a rebuild
            r.settings = RenderSettings(primary="rays", bvh_build=build)
            f = r.render(rig, aux=("triangle", "hdr"))
            frames[build] = (np.stack([f.left.aux["triangle"], f.right.aux["triangle"]]),
                             np.stack([f.left.aux["hdr"], f.right.aux["hdr"]]))
            assert r.accel.build == build
            assert (r.accel.bvh.reference_count > scene.triangle_count) == (build == "sbvh")
    finally:
        r.release()
    assert np.array_equal(frames["sbvh"][0], frames["sah"][0])
    hdr = frames["sah"][1]
    assert np.abs(frames["sbvh"][1] - hdr).max() <= 1e-5 * max(1.0, float(hdr.max()))
    with pytest.raises(ValueError, match="unknown BVH build 'kd'"):
        RenderSettings(bvh_build="kd")


def test_bench_bvh_and_cli_flag(tmp_path):
    from conftest import quick_bench, run_rayvr
    result = quick_bench("bvh", tmp_path)
    rows = result["rows"]
    assert {r["bvh_build"] for r in rows} == {"sah", "sbvh"}
    assert {"primary", "shadow", "reflect", "diffuse"} <= {r["rays_kind"] for r in rows}
    for r in rows:
        assert r["agree_with_first_build"] >= 0.99 and r["pair_node_visits"] > 0
        assert 1.0 <= r["references_per_triangle"] <= 1.3
    sah = {r["rays_kind"]: r for r in rows if r["bvh_build"] == "sah"}
    assert all(r["sah_cost"] < sah[r["rays_kind"]]["sah_cost"] for r in rows if r["bvh_build"] == "sbvh")
    bad = run_rayvr("capture", "--bvh-build", "kd", "--out", tmp_path / "x")
    assert bad.returncode != 0 and "unknown BVH build 'kd'" in bad.stderr and "Traceback" not in bad.stderr
