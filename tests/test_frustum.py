"""Tile frustum culling (accel/frustum.py, glsl/accel/tile_cull.comp) against per-ray traversal."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from conftest import merge, quad
from rayvr.accel.bvh import build_bvh, trace_reference
from rayvr.accel.frustum import entry_subtrees, tile_frusta, tile_order
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer
from rayvr.gl.gpu_layout import TILE_RAYS
from test_traversal_gpu import agreement


def scene():
    """A finely cut ball in front of a wall, on a long floor: silhouettes, grazing floor, open sky."""
    ball = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    v, f, _ = merge((np.asarray(ball.vertices) + [0, 1, -6], ball.faces),
                    quad((0, 1, -12), (6, 0, 0), (0, 3, 0)),
                    quad((0, 0, -50), (6, 0, 0), (0, 0, 50)))
    return v.astype(np.float32), f


def pinhole(w, h, eye=(0, 0.05, 0), fov=1.0, look=(0, 0, -1), up=(0, 1, 0)):
    """Row-major camera rays reordered into tiles (frustum.tile_order)."""
    look = np.asarray(look, float) / np.linalg.norm(look)
    right = np.cross(look, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, look)
    ys, xs = np.mgrid[0:h, 0:w]
    sx, sy = (xs + 0.5) / w * 2 - 1, 1 - (ys + 0.5) / h * 2
    d = look + fov * (sx[..., None] * right + sy[..., None] * up * h / w)
    d = d.reshape(-1, 3)[tile_order(w, h)]
    return np.broadcast_to(np.asarray(eye, float), d.shape).astype(np.float32), d.astype(np.float32)


def assert_culled_equals_per_ray(rt, o, d, tmax=np.float32(3e38), **kw):
    info = {}
    full = rt.trace(o, d, tmax=tmax, **kw)
    tiled = rt.trace(o, d, tmax=tmax, tiles=True, tile_info=info, **kw)
    frac, err = agreement(full.prim, full.t, tiled.prim, tiled.t, rel=0.0)
    assert frac == 1.0 and err == 0.0, f"tile-culled agrees with per-ray on {frac:.4%}"
    same = full.prim == tiled.prim
    assert np.array_equal(full.u[same], tiled.u[same]) and np.array_equal(full.v[same], tiled.v[same])
    occ = rt.trace(o, d, tmax=tmax, mode="any", **kw)
    assert np.array_equal(occ, rt.trace(o, d, tmax=tmax, mode="any", tiles=True, **kw))
    return full, info


def test_tile_order_is_a_permutation_of_blocks():
    order = tile_order(40, 20, layers=2)
    assert np.array_equal(np.sort(order), np.arange(40 * 20 * 2))
    first = order[:TILE_RAYS]                    # the first tile: a 16 x 8 block at the corner
    assert set((first % 40).tolist()) == set(range(16)) and set((first // 40).tolist()) == set(range(8))
    # layer 1 follows layer 0 entirely
    assert (order[:800] < 800).all() and (order[800:] >= 800).all()


def test_numpy_frusta_hold_every_ray_point():
    rng = np.random.default_rng(3)
    o, d = pinhole(48, 32)
    o = o + rng.uniform(-0.05, 0.05, o.shape).astype(np.float32)   # a lens: origins spread
    planes, status = tile_frusta(o, d)
    assert (status == 1).all()
    for t in (0.0, 0.3, 7.0, 1e4):
        p = o.astype(np.float64) + t * d
        tile = np.arange(len(o)) // TILE_RAYS
        side = np.einsum("nkj,nj->nk", planes[tile, :4, :3], p) - planes[tile, :4, 3]
        assert (side <= 0).all()
    # directions over a half-space: no culling; no valid ray: empty
    d2 = d.copy()
    d2[:TILE_RAYS] = rng.normal(size=(TILE_RAYS, 3))
    d2[TILE_RAYS:2 * TILE_RAYS] = 0
    _, status = tile_frusta(o, d2)
    assert status[0] == 2 and status[1] == 0 and (status[2:] == 1).all()


def test_tile_culled_equals_per_ray_through_silhouettes_floor_and_sky(gl):
    v, f = scene()
    bvh = build_bvh(v, f)
    rt = RayTracer(gl, GpuBvh(gl, bvh))
    o, d = pinhole(128, 96)
    full, info = assert_culled_equals_per_ray(rt, o, d)
    ball = full.prim < 20 * 4 ** 4   # the icosphere comes first
    assert 0.02 < ball.mean() < 0.5 and (full.prim == MISS).mean() > 0.1   # silhouettes and sky
    planes, status = tile_frusta(o, d)
    assert (status == 1).all()
    finite = np.isfinite(planes) & np.isfinite(info["planes"])
    assert np.allclose(info["planes"][finite], planes[finite], rtol=1e-4, atol=1e-4)
    # The cut is a real one: lists hold fewer entries than a tile's triangles, and every ray's hit
    # lies under an entry of its tile.
    counts = info["counts"]
    assert counts.max() <= info["entries"].shape[1]
    empty = np.flatnonzero(counts == 0)          # sky tiles: the frustum meets no box at all
    assert len(empty) and (full.prim.reshape(-1, TILE_RAYS)[empty] == MISS).all()
    slot_of = np.argsort(bvh.prim_ids)
    covered = []
    for tile in range(len(counts)):
        ranges = entry_subtrees(bvh, info["entries"][tile, :counts[tile]])
        covered.append(sum(b - a for a, b in ranges))
        rays = np.arange(tile * TILE_RAYS, min(len(o), (tile + 1) * TILE_RAYS))
        hit = full.prim[rays] != MISS
        slots = slot_of[full.prim[rays][hit]]
        assert all(any(a <= s < b for a, b in ranges) for s in slots)
    assert np.mean(covered) < 0.5 * len(f)   # most triangles are culled for a typical tile


def test_tile_culled_grazing_lens_and_partial_tiles(gl):
    v, f = scene()
    rt = RayTracer(gl, GpuBvh(gl, build_bvh(v, f)))
    # grazing: eye just above the floor, looking along it
    o, d = pinhole(64, 40, eye=(0.3, 1e-3, 10), look=(0, -1e-4, -1), fov=0.3)
    assert_culled_equals_per_ray(rt, o, d)
    # a lens: origins over a disk, every ray through its pixel's focus point; and a partial last tile
    rng = np.random.default_rng(5)
    o, d = pinhole(50, 33)
    focus = o + d * 6.0
    o = (o + np.c_[rng.uniform(-0.2, 0.2, (len(o), 2)), np.zeros(len(o))]).astype(np.float32)
    assert len(o) % TILE_RAYS
    assert_culled_equals_per_ray(rt, o, (focus - o).astype(np.float32))


def test_tile_culled_shadow_rays_invalid_and_wide_tiles(gl):
    v, f = scene()
    bvh = build_bvh(v, f)
    rt = RayTracer(gl, GpuBvh(gl, bvh))
    o, d = pinhole(64, 48)
    hits = rt.trace(o, d)
    h = np.flatnonzero(hits.prim != MISS)
    p = (o[h] + hits.t[h, None] * d[h]).astype(np.float32)
    light = np.float32([2, 6, -3])
    so = (p + (light - p) * 1e-4).astype(np.float32)
    full, _ = assert_culled_equals_per_ray(rt, so, (light - so).astype(np.float32), tmax=np.float32(1.0))
    # tiles with invalid rays (zero, NaN direction) and a tile of rays in every direction
    rng = np.random.default_rng(9)
    o2, d2 = pinhole(32, 16)
    d2[3], d2[40], d2[200:230] = 0, np.nan, 0
    d2[TILE_RAYS * 2:TILE_RAYS * 3] = rng.normal(size=(TILE_RAYS, 3))
    _, info = assert_culled_equals_per_ray(rt, o2, d2)
    wide = info["counts"][2]
    assert wide == 2 and set(info["entries"][2, :2].tolist()) == {0, 1}   # not culled: the root's children
    # against the numpy reference too (float64): same triangles
    prim, t, _, _ = trace_reference(bvh, o2, d2)
    tiled = rt.trace(o2, d2, tiles=True)
    frac, err = agreement(tiled.prim, tiled.t, prim, t)
    assert frac >= 0.999 and err <= 1e-5


def test_tile_culling_needs_the_binary_layout(gl):
    v, f = scene()
    rt = RayTracer(gl, GpuBvh(gl, build_bvh(v, f), layout="bvh4"))
    o, d = pinhole(16, 8)
    with pytest.raises(ValueError, match="bvh2 layout"):
        rt.trace(o, d, tiles=True)


def entry_near(bvh, entries, c):
    """Nearest point along c of each entry's box (min over the box of c.x), float64, from the packed
    GPU nodes: the key tile_cull.comp sorts a tile's entries by."""
    nodes = bvh.pack_nodes().reshape(-1, 4, 4).astype(np.float64)
    e = np.asarray(entries, np.int64)
    parent, side = nodes[e >> 1], e & 1
    box = np.where(side[:, None] == 0, parent[:, 0:2].reshape(-1, 8)[:, :6], parent[:, 1:3].reshape(-1, 8)[:, 2:])
    lo, hi = box[:, 0::2], box[:, 1::2]
    return (0.5 * (lo + hi)) @ c - (0.5 * (hi - lo)) @ np.abs(c)


def test_tile_entries_front_to_back_cut_the_work_not_the_answer(gl):
    """Entries are sorted nearest first along the tile's central direction; the hits stay exactly
    those of tree order and of per-ray traversal, and a ray does less work (GPU counts)."""
    v, f = scene()
    bvh = build_bvh(v, f)
    gpu = GpuBvh(gl, bvh)
    o, d = pinhole(128, 96)
    info, work = {}, {}
    for name, rt, tiles in (("ray", RayTracer(gl, gpu), False), ("tree", RayTracer(gl, gpu, tile_sort=False), True),
                            ("sorted", RayTracer(gl, gpu), True)):
        work[name] = {}
        info[name] = {}
        hits = rt.trace(o, d, tiles=tiles, work=work[name],
                        tile_info=info[name] if tiles else None)
        work[name]["hits"] = hits
    for name in ("tree", "sorted"):
        assert np.array_equal(work[name]["hits"].prim, work["ray"]["hits"].prim)
        assert np.array_equal(work[name]["hits"].t, work["ray"]["hits"].t)
    sorted_info, tree_info = info["sorted"], info["tree"]
    assert np.array_equal(sorted_info["counts"], tree_info["counts"])
    reordered = 0
    for tile in np.flatnonzero(sorted_info["counts"] > 1):
        n = sorted_info["counts"][tile]
        ent, tree = sorted_info["entries"][tile, :n], tree_info["entries"][tile, :n]
        assert sorted(ent.tolist()) == sorted(tree.tolist())           # the same cut, reordered
        key = entry_near(bvh, ent, sorted_info["planes"][tile, 4, :3].astype(np.float64))
        assert (np.diff(key) >= -1e-5 * (1 + np.abs(key[1:]))).all(), key
        reordered += not np.array_equal(ent, tree)
    assert reordered > 0
    tri = {k: int(work[k]["triangle_tests"].sum()) for k in work}
    nodes = {k: int(work[k]["node_visits"].sum() + work[k]["entry_tests"].sum()) for k in work}
    assert tri["sorted"] < tri["tree"] and nodes["sorted"] < nodes["tree"], (tri, nodes)
    assert (work["ray"]["entry_tests"] == 0).all() and (work["ray"]["node_visits"] >= 1).all()
    # the counters count: a ray that hits has tested a triangle; tiles' rays test their entries
    hit = work["ray"]["hits"].prim != MISS
    assert (work["ray"]["triangle_tests"][hit] >= 1).all()
    tile_of = np.arange(len(o)) // TILE_RAYS
    valid = sorted_info["counts"][tile_of] > 0
    assert (work["sorted"]["entry_tests"][valid] >= 1).all()
    assert (work["sorted"]["entry_tests"] <= sorted_info["counts"][tile_of]).all()
