"""GPU traversal (glsl/accel) against the numpy reference and against Embree; robustness cases."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import SHARED_SCENES
from rayvr.accel.bvh import BufferTooLargeError, build_bvh, offset_ray, trace_reference
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer

def load_mesh(rel):
    p = SHARED_SCENES / rel
    if not p.exists():
        pytest.skip(f"{p} not found: the shared scenes folder is absent")
    import trimesh
    m = trimesh.load(p, force="mesh")
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int64)


def tracer(gl, verts, faces, **build):
    return RayTracer(gl, GpuBvh(gl, build_bvh(verts, faces, **build)))


def embree_scene(verts, faces):
    pytest.importorskip("embreex")
    from embreex import mesh_construction, rtcore_scene
    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, np.asarray(verts, np.float32), np.asarray(faces, np.int32))
    return scene


def embree_closest(scene, o, d):
    r = scene.run(np.asarray(o, np.float32), np.asarray(d, np.float32), output=1)
    prim = r["primID"].astype(np.int64)
    t = np.where(prim >= 0, r["tfar"].astype(np.float64), np.inf)
    return np.where(prim >= 0, prim, MISS).astype(np.uint32), t


def agreement(prim, t, ref_prim, ref_t, rel=1e-5):
    """(fraction agreeing, max relative t error on same-triangle hits). Two different triangles at the
    same distance (a ray through a shared edge or vertex) count as agreeing: an edge tie."""
    same = prim == ref_prim
    both = (prim != MISS) & (ref_prim != MISS)
    with np.errstate(invalid="ignore"):   # inf - inf on misses
        tie = ~same & both & (np.abs(t - ref_t) <= rel * np.abs(ref_t))
    hit = same & both
    err = np.abs(t[hit] - ref_t[hit]) / np.abs(ref_t[hit]) if hit.any() else np.zeros(1)
    return (same | tie).mean(), float(err.max())


def rays_at(verts, n, seed, spread=0.2):
    rng = np.random.default_rng(seed)
    lo, hi = verts.min(0), verts.max(0)
    c, r = (lo + hi) / 2, np.linalg.norm(hi - lo)
    o = c + rng.normal(size=(n, 3)) * r
    return o, c + rng.normal(size=(n, 3)) * r * spread - o


def soup(n, seed=0):
    rng = np.random.default_rng(seed)
    v = (rng.uniform(-5, 5, (n, 1, 3)) + rng.normal(size=(n, 3, 3))).reshape(-1, 3).astype(np.float32)
    return v, np.arange(3 * n).reshape(n, 3)


# ---------------------------------------------------------------- against the references

def test_gpu_matches_reference_on_soup(gl):
    v, f = soup(2000)
    bvh = build_bvh(v, f)
    rt = RayTracer(gl, GpuBvh(gl, bvh))
    o, d = rays_at(v, 4000, seed=1)
    hits = rt.trace(o, d)
    prim, t, u, w = trace_reference(bvh, o, d)
    assert 0.3 < (prim != MISS).mean() < 0.95
    frac, err = agreement(hits.prim, hits.t, prim, t)
    assert frac >= 0.999 and err <= 1e-5
    same = (hits.prim == prim) & (prim != MISS)
    assert np.abs(hits.u[same] - u[same]).max() < 1e-4 and np.abs(hits.v[same] - w[same]).max() < 1e-4
    occ = rt.trace(o, d, tmax=0.7, mode="any")
    assert (occ == trace_reference(bvh, o, d, tmax=0.7, any_hit=True)).mean() >= 0.999
    # tmin cuts the near hits off
    far = rt.trace(o, d, tmin=np.where(np.isfinite(hits.t), hits.t * 1.0001, 0))
    assert (far.t[np.isfinite(far.t)] > hits.t[np.isfinite(far.t)]).all()


@pytest.mark.parametrize("rel", ["stanford_bunny/bun_zipper_res2.ply", "sponza_dabrovic/sponza.obj"])
def test_gpu_matches_embree(gl, rel):
    v, f = load_mesh(rel)
    scene = embree_scene(v, f)
    rt = tracer(gl, v, f)
    rng = np.random.default_rng(7)
    if "sponza" in rel:   # inside the building, all directions
        lo, hi = v.min(0), v.max(0)
        o = rng.uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), (4000, 3))
        d = rng.normal(size=(4000, 3))
    else:
        o, d = rays_at(v, 4000, seed=8)
    o, d = o.astype(np.float32), (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    hits = rt.trace(o, d)
    eprim, et = embree_closest(scene, o, d)
    assert (eprim != MISS).mean() > 0.3
    frac, err = agreement(hits.prim, hits.t, eprim, et)
    assert frac >= 0.999, f"only {frac:.4%} of rays agree with Embree"
    assert err <= 1e-5, f"relative t error {err:.2e}"

    # Shadow rays from the hit points (offset off the surface) to random points: occlusion agrees.
    hit = np.flatnonzero(hits.prim != MISS)
    tri = v[f[hits.prim[hit]]]
    p = tri[:, 0] + hits.u[hit, None] * (tri[:, 1] - tri[:, 0]) + hits.v[hit, None] * (tri[:, 2] - tri[:, 0])
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n *= -np.sign((n * d[hit]).sum(1, keepdims=True))
    so = offset_ray(p, n)
    target = so + rng.normal(size=so.shape).astype(np.float32) * np.linalg.norm(v.max(0) - v.min(0)) * 0.3
    sd = (target - so).astype(np.float32)
    occ = rt.trace(so, sd, tmin=0.0, tmax=1.0, mode="any")
    eocc = scene.run(so, sd, dists=np.ones(len(so), np.float32), query="OCCLUDED") >= 0
    assert 0.05 < eocc.mean() < 0.99
    assert (occ == eocc).mean() >= 0.999, f"occlusion agrees on {(occ == eocc).mean():.4%}"


def test_refit_on_gpu(gl):
    v, f = soup(500, seed=3)
    bvh = build_bvh(v, f)
    gb = GpuBvh(gl, bvh)
    rt = RayTracer(gl, gb)
    moved = (v * 1.3 + np.sin(v[:, [1, 2, 0]])).astype(np.float32)
    bvh.refit(moved)
    gb.update()
    o, d = rays_at(moved, 2000, seed=4)
    hits = rt.trace(o, d)
    prim, t, _, _ = trace_reference(bvh, o, d)
    frac, err = agreement(hits.prim, hits.t, prim, t)
    assert frac >= 0.999 and err <= 1e-5


def test_too_big_for_device_is_a_clear_error(gl):
    v, f = soup(100)
    bvh = build_bvh(v, f)
    with pytest.raises(BufferTooLargeError, match="bvh_nodes|bvh_triangles"):
        GpuBvh(gl, bvh, limit=1024)
    deep = build_bvh(v, f)
    deep.depth = deep.depth + 60   # pretend the tree is deeper than the GPU stack
    with pytest.raises(ValueError, match="stack"):
        GpuBvh(gl, deep)


# ---------------------------------------------------------------- robustness

def cube():
    import trimesh
    m = trimesh.creation.box(extents=(2, 2, 2))
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces)


def cube_edge_rays():
    """Rays along each axis, both ways, at cube()'s faces, edges and corners and past them, then a
    ray grazing an edge, one just off it, a zero direction and a NaN one: (origins, directions,
    which of the axis rays, the first ones, meet the cube)."""
    grid = np.array([-1.5, -1.0, -0.5, 0.0, 0.3, 1.0, 1.5], np.float32)
    a, b = [x.ravel() for x in np.meshgrid(grid, grid)]
    o, d = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            oo = np.zeros((len(a), 3), np.float32)
            oo[:, axis] = -5.0 * sign
            oo[:, (axis + 1) % 3], oo[:, (axis + 2) % 3] = a, b
            dd = np.zeros_like(oo)
            dd[:, axis] = sign
            o.append(oo)
            d.append(dd)
    o.append(np.array([[-5, 1, 0], [-5, 1.0001, 0], [0, 0, 0], [0, 0, 0]], np.float32))
    d.append(np.array([[1, 0, 0], [1, 0, 0], [0, 0, 0], [np.nan, 0, 1]], np.float32))
    o, d = np.concatenate(o), np.concatenate(d)
    return o, d, np.concatenate([(np.abs(a) <= 1) & (np.abs(b) <= 1)] * 6)


def test_axis_parallel_rays_hit_faces_edges_and_corners(gl):
    v, f = cube()
    rt = tracer(gl, v, f)
    grid = np.array([-1.5, -1.0, -0.5, 0.0, 0.3, 1.0, 1.5], np.float32)
    a, b = [x.ravel() for x in np.meshgrid(grid, grid)]
    inside = (np.abs(a) <= 1) & (np.abs(b) <= 1)
    for axis in range(3):
        for sign in (1.0, -1.0):
            o = np.zeros((len(a), 3), np.float32)
            o[:, axis] = -5.0 * sign
            o[:, (axis + 1) % 3], o[:, (axis + 2) % 3] = a, b
            d = np.zeros_like(o)
            d[:, axis] = sign
            hits = rt.trace(o, d)
            assert not np.isnan(hits.t).any() and not np.isnan(hits.u).any() and not np.isnan(hits.v).any()
            # on the face, its edges (shared by two triangles or lying in a side face) and corners
            assert (hits.prim[inside] != MISS).all(), f"axis {axis} sign {sign}: ray slipped through"
            assert np.allclose(hits.t[inside], 4.0, rtol=1e-6)
            assert (hits.prim[~inside] == MISS).all()
            assert np.array_equal(rt.trace(o, d, tmax=10.0, mode="any"), inside)


def test_grazing_and_degenerate_directions(gl):
    v, f = cube()
    rt = tracer(gl, v, f)
    o = np.array([
        [-5, 1, 0],          # in the plane of the top face: hits the side face's top edge at t = 4
        [-5, 1.0001, 0],     # just above the top face, parallel: misses
        [-5, 0.999999, 0.2],
        [-5, 1, 0],          # almost parallel to the top face, dipping into the side face
        [0, 0, 0],           # zero-length direction
        [0, 0, 0],           # NaN direction
        [0, 0, 0],           # infinite direction
        [0, 0, -5],          # tmax <= tmin
    ], np.float32)
    d = np.array([[1, 0, 0], [1, 0, 0], [1, 0, 0], [1, -1e-7, 0], [0, 0, 0], [np.nan, 0, 1],
                  [np.inf, 0, 1], [0, 0, 1]], np.float32)
    tmax = np.array([np.inf] * 7 + [-1.0], np.float32)
    hits = rt.trace(o, d, tmax=tmax)
    assert not np.isnan(hits.t).any() and not np.isnan(hits.u).any() and not np.isnan(hits.v).any()
    assert hits.prim[0] != MISS and hits.t[0] == pytest.approx(4.0)
    assert hits.prim[1] == MISS
    assert hits.prim[2] != MISS and hits.t[2] == pytest.approx(4.0)
    assert hits.prim[3] != MISS and hits.t[3] == pytest.approx(4.0)
    assert (hits.prim[4:] == MISS).all() and np.isinf(hits.t[4:]).all()
    assert not rt.trace(o[4:], d[4:], tmax=tmax[4:], mode="any").any()


def test_watertight_through_vertices_and_edges(gl):
    # A bumpy height field; rays from random points above aimed exactly at its vertices and edge
    # midpoints must all hit something (no leaks between triangles).
    n = 16
    rng = np.random.default_rng(11)
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    z = rng.uniform(0, 0.05, x.shape)
    v = np.stack([x, y, z], -1).reshape(-1, 3).astype(np.float32) * np.float32(3.7) + np.float32(0.1)
    i = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    q = np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 4)
    f = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    rt = tracer(gl, v, f)
    interior = v[i[1:-1, 1:-1].ravel()]
    mids = ((v[f[:, 0]] + v[f[:, 1]]) * 0.5)
    targets = np.concatenate([interior, mids[(mids[:, :2] > 0.2).all(1) & (mids[:, :2] < 3.7).all(1)]])
    o = targets + np.array([0, 0, 2], np.float32) + rng.normal(scale=0.3, size=targets.shape).astype(np.float32)
    hits = rt.trace(o, targets - o)
    assert (hits.prim != MISS).all(), f"{(hits.prim == MISS).sum()} rays leaked through the mesh"
    hits = rt.trace(targets + np.float32([0, 0, 1]), np.tile(np.float32([0, 0, -1]), (len(targets), 1)))
    assert (hits.prim != MISS).all()


def icosphere(scale, shift):
    import trimesh
    m = trimesh.creation.icosphere(subdivisions=3)
    return (np.asarray(m.vertices) * scale + shift).astype(np.float32), np.asarray(m.faces)


@pytest.mark.parametrize("scale,shift", [(1e-3, 0.0), (1e-3, 1.0), (1.0, 1e5), (1e5, 0.0), (1e5, 1e5)])
def test_offset_ray_avoids_self_intersection(gl, scale, shift):
    v, f = icosphere(scale, shift)
    rt = tracer(gl, v, f)
    rng = np.random.default_rng(5)
    c = np.float32(shift)
    away = rng.normal(size=(3000, 3))
    away *= rng.uniform(1.5, 4, (3000, 1)) / np.linalg.norm(away, axis=1, keepdims=True)
    o = (c + away * scale).astype(np.float32)   # outside the sphere: reflections must escape
    target = (c + rng.normal(size=(3000, 3)) * 0.5 * scale).astype(np.float32)
    d = target - o
    first = rt.trace(o, d)
    hit = first.prim != MISS
    assert hit.mean() > 0.3
    # Mirror reflection off a convex surface leaves it: nothing else to hit.
    refl = rt.trace(o, d, mode="reflect")
    assert (refl.prim[hit] == MISS).all(), f"{(refl.prim[hit] != MISS).sum()} reflected rays re-hit the sphere"
    # Continuing through the surface: the next hit is the far side, never the entry triangle.
    thru = rt.trace(o, d, mode="through")
    assert (thru.prim[hit] != MISS).all() and (thru.prim[hit] != first.prim[hit]).all()


def test_without_offset_rays_do_self_intersect(gl):
    # The control for the test above: starting exactly at the computed hit point re-hits the surface.
    v, f = icosphere(1.0, 1e5)
    rt = tracer(gl, v, f)
    rng = np.random.default_rng(5)
    o = (1e5 + rng.normal(size=(3000, 3)) * 3).astype(np.float32)
    d = (1e5 + rng.normal(size=(3000, 3)) * 0.5).astype(np.float32) - o
    hit = rt.trace(o, d).prim != MISS
    refl = rt.trace(o, d, mode="reflect", offset=False)
    assert (refl.prim[hit] != MISS).mean() > 0.05


def test_empty_and_single_triangle_scenes(gl):
    rt = tracer(gl, np.zeros((0, 3), np.float32), np.zeros((0, 3), int))
    hits = rt.trace([[0, 0, 0]], [[0, 0, 1]])
    assert hits.prim[0] == MISS and not rt.trace([[0, 0, 0]], [[0, 0, 1]], mode="any")[0]
    rt = tracer(gl, np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), [[0, 1, 2]])
    hits = rt.trace([[0.25, 0.5, 2], [0.25, 0.5, -2], [2, 2, 2]], [[0, 0, -1], [0, 0, 1], [0, 0, -1]])
    assert list(hits.prim) == [0, 0, MISS]
    assert hits.t[:2] == pytest.approx([2, 2]) and hits.u[0] == pytest.approx(0.25) and hits.v[0] == pytest.approx(0.5)
