"""The photon map's GPU steps against numpy (accel/photon_map.py): cell keys and counts, the prefix
sum, the radix sort, radius queries through the hash grid and the kd-tree == brute force, and the
density estimate (no heap / heap) on photons whose irradiance is known."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.accel import photon_map as pm


def random_photons(n, seed=1, lo=(-1.0, -0.5, -2.0), hi=(2.0, 1.5, 0.5), empty=0.1):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(lo, hi, (n, 3)).astype(np.float32)
    # clusters: many photons in few cells, as on a lit floor
    pos[: n // 4] = (pos[: n // 4] * 0.05 + np.float32(0.3)).astype(np.float32)
    nrm = rng.normal(size=(n, 3))
    power = rng.uniform(0, 1, (n, 3)).astype(np.float32)
    valid = rng.uniform(size=n) > empty
    return pos, nrm / np.linalg.norm(nrm, axis=1, keepdims=True), power, valid, np.array(lo), np.array(hi)


@pytest.fixture(scope="module")
def built(gl):
    from photon_gpu import GpuPhotonMap  # tests/photon_gpu.py

    pos, nrm, power, valid, lo, hi = random_photons(5000)
    grid = pm.grid_shape(lo, hi, 0.11)
    rec = pm.pack_photons(pos, nrm, power, extra=valid.astype(np.uint32))
    g = GpuPhotonMap(gl, rec, grid)
    g.build(keep_keys=True)
    yield g, pos, nrm, power, valid, grid
    g.release()


def test_grid_shape_pads_and_caps():
    g = pm.grid_shape((0, 0, 0), (1, 2, 3), 0.5)
    assert g.cell == 0.5 and g.dims == (5, 7, 9)  # 2, 4, 6 cells + the top face + 2 padding
    big = pm.grid_shape((0, 0, 0), (100, 100, 100), 0.001, max_cells=10_000)
    assert big.cells <= 10_000 and big.cell > 0.001


def test_gpu_cells_counts_and_scan_equal_numpy(built):
    g, pos, _, _, valid, grid = built
    keys = g.cell_keys
    want = pm.grid_cells(grid, pos, valid)
    assert np.array_equal(keys[:, 1], np.arange(g.n))
    assert np.mean(keys[:, 0] == want) > 0.999  # float rounding on a cell face may differ, nothing else
    want = keys[:, 0]
    start = g.read_u32(g.start, grid.cells + 2)
    _, ref_start = pm.build_grid(grid, want)
    assert np.array_equal(start, ref_start)
    assert start[-1] == g.n and start[grid.dead] == valid.sum()


def test_gpu_scan_levels_equal_numpy(gl):
    from rayvr.frame.passes.prefix_scan import Scan, scan_words

    rng = np.random.default_rng(3)
    ctx = gl.ctx
    scan = Scan(ctx)
    for n in (1, 1023, 1024, 1025, 70_000, 1_100_000):  # one block, two levels, three levels
        data = rng.integers(0, 50, n).astype(np.uint32)
        buf = ctx.buffer(np.concatenate([data, np.zeros(scan_words(n) - n, np.uint32)]).tobytes())
        scan.run(buf, n)
        got = np.frombuffer(buf.read(), np.uint32)[:n]
        assert np.array_equal(got, pm.exclusive_scan(data)[:-1]), n
        buf.release()
    scan.release()


def test_gpu_radix_sort_is_numpys_stable_sort(built):
    g, *_ = built
    keys = g.cell_keys
    got = g.read_u32(g.sorted_keys, g.n, 2)
    order = np.argsort(keys[:, 0], kind="stable")
    assert np.array_equal(got, keys[order])
    mapped = pm.unpack_photons(g.map.read())
    photons = pm.unpack_photons(g.photons.read())
    assert np.array_equal(mapped["position"], photons["position"][order])


@pytest.mark.parametrize("radius", [0.04, 0.11])
def test_gpu_grid_query_is_brute_force(built, radius):
    g, pos, _, _, valid, grid = built
    order = g.read_u32(g.sorted_keys, g.n, 2)[:, 1]
    rng = np.random.default_rng(7)
    pts = np.concatenate([pos[rng.choice(g.n, 150)] + rng.normal(0, 0.03, (150, 3)),
                          rng.uniform(grid.origin, np.array(grid.origin) + np.array(grid.dims) * grid.cell, (50, 3))])
    pts = pts.astype(np.float32)
    got = g.query(pts, radius, capacity=2048)
    start = g.read_u32(g.start, grid.cells + 2)
    sorted_pos = pos[order]
    hits = 0
    for p, found in zip(pts, got):
        assert found is not None
        want = set(pm.brute_query(pos, p, radius, valid).tolist())
        assert set(order[found].tolist()) == want and len(found) == len(want)
        assert set(order[pm.grid_query(grid, sorted_pos, start, p, radius)].tolist()) == want  # numpy grid path
        hits += len(want)
    assert hits > 200  # the queries do find photons


def test_kdtree_query_is_brute_force_numpy_and_gpu(built):
    g, pos, _, _, valid, _ = built
    rec = g.kdtree()
    n = int(rec[0, 0])
    tree_pos = rec[1:, 0:3].view(np.float32)
    axis = rec[1:, 7]
    vpos = pos[valid]
    assert n == valid.sum() and sorted(map(tuple, tree_pos)) == sorted(map(tuple, vpos))
    rng = np.random.default_rng(9)
    pts = (vpos[rng.choice(n, 120)] + rng.normal(0, 0.05, (120, 3))).astype(np.float32)
    got = g.query(pts, 0.09, capacity=2048, kdtree=True)
    for p, found in zip(pts, got):
        want = {tuple(x) for x in vpos[pm.brute_query(vpos, p, 0.09)]}
        assert {tuple(x) for x in tree_pos[pm.kdtree_query(tree_pos, axis, p, 0.09)]} == want
        assert {tuple(x) for x in tree_pos[found]} == want and len(found) == len(want)


def test_density_on_uniform_plane_matches_irradiance():
    """Photons spread uniformly over a plane with total power P over area A: E = P / A, within
    the Monte Carlo error of a count in a disc (Poisson: relative sigma 1/sqrt(expected count))."""
    rng = np.random.default_rng(5)
    n, side, total = 200_000, 4.0, 3.0
    pos = np.zeros((n, 3), np.float32)
    pos[:, [0, 2]] = rng.uniform(-side / 2, side / 2, (n, 2))
    nrm = np.tile([0.0, 1.0, 0.0], (n, 1))
    power = np.full((n, 3), total / n)
    e = total / side ** 2
    r = 0.1
    expected = n * np.pi * r * r / side ** 2
    for x in ((0, 0, 0), (0.7, 0, -1.1)):
        got = pm.density(pos, nrm, power, x, (0, 1, 0), r)
        assert abs(got[0] / e - 1) < 4 / np.sqrt(expected), (got, e)
        k = pm.density(pos, nrm, power, x, (0, 1, 0), r, k=64)
        assert abs(k[0] / e - 1) < 4 / np.sqrt(64), (k, e)
    assert pm.density(pos, nrm, power, (0, 0, 0), (0, -1, 0), r).sum() == 0  # the other side gets nothing


def test_oct_normals_round_trip():
    rng = np.random.default_rng(2)
    n = rng.normal(size=(1000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(pm.oct_decode(pm.oct_encode(n)) - n).max() < 1e-3


def test_gpu_sort_in_rows_of_work_groups(gl, monkeypatch):
    """More work groups than one dispatch row holds (65535 on real GPUs; 7 here): rows of groups,
    the spare groups of the last row idle, the result still numpy's stable sort."""
    from rayvr.frame.passes import prefix_scan as photon_scan
    from rayvr.frame.passes.radix_sort import RadixSort, table_words

    monkeypatch.setattr(photon_scan, "MAX_GROUPS", 7)
    rng = np.random.default_rng(4)
    n = 5000  # 20 groups of 256: 3 rows of 7
    keys = np.stack([rng.integers(0, 70_000, n), np.arange(n)], 1).astype(np.uint32)
    ctx = gl.ctx
    a, b = ctx.buffer(keys.tobytes()), ctx.buffer(bytes(keys.nbytes))
    table = ctx.buffer(bytes(4 * table_words(n)))
    sorter = RadixSort(ctx)
    out = sorter.sort(a, b, table, n, 17)
    got = np.frombuffer(out.read(), np.uint32).reshape(n, 2)
    assert np.array_equal(got, keys[np.argsort(keys[:, 0], kind="stable")])
    for x in (a, b, table):
        x.release()
    sorter.release()


def test_lights_emit_in_proportion_to_power():
    from rayvr.frame.effects.photon.trace import light_power, light_table
    from rayvr.scene.loader import Light

    class S:
        lights = [Light("point", intensity=1.0), Light("point", intensity=3.0),
                  Light("rect", intensity=2.0, u=(0.5, 0, 0), v=(0, 0, 0.25)), Light("rect", u=(1, 0, 0))]  # zero area

    phi = light_power(S, 1.0)
    assert np.allclose(phi[:, 0], [4 * np.pi, 12 * np.pi, np.pi * 2.0 * 0.5, 0.0])
    t = light_table(S, 1000, 1.0)
    assert np.allclose(np.diff(np.concatenate([[0], t[:, 3]])), phi[:, 0] / phi[:, 0].sum(), atol=1e-6)
    assert np.allclose(t[:3, 0], phi[:, 0].sum() / 1000)  # every path carries the same power
    assert np.isfinite(t).all()


def test_shipped_photon_room_config_puts_the_room_on_photon():
    from pathlib import Path

    from rayvr.scene.materials import load_config
    from rayvr.scene.loader import load

    cfg = load_config(Path(__file__).resolve().parents[1] / "rayvr" / "assets" / "photon_room.toml")
    got = {n: a.effect for n, a in zip(load(None).material_names(), cfg.assign(load(None).material_names()))}
    assert got["ceiling"] == got["walls"] == "photon" and got["mirror"] == "reflections" and got["light"] == "raster"
