"""GPU refit (accel/refit.py) against the numpy refit, and traces after it against a rebuilt BVH."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.accel.bvh import build_bvh
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer
from rayvr.accel.refit import GpuRefit
from test_traversal_gpu import agreement, rays_at, soup


def move(v, k=1.0):
    m = (v * (1 + 0.3 * k) + k * np.sin(v[:, [1, 2, 0]] * 1.7)).astype(np.float32)
    m[::7, 0] = 0.0  # box faces at 0 and near it, where the widening's FACE_SLACK floor decides
    m[1::7, 1] = np.float32(3e-9) * k
    return m


@pytest.mark.parametrize("n,leaf", [(1500, 8), (300, 1), (1, 8)])
def test_gpu_refit_equals_numpy_refit_bit_for_bit(gl, n, leaf):
    v, f = soup(n, seed=11)
    host = build_bvh(v, f, max_leaf_size=leaf)
    gpu_side = build_bvh(v, f, max_leaf_size=leaf)
    gb = GpuBvh(gl, gpu_side)
    refit = GpuRefit(gl, gb)
    for k in (1.0, -0.5):           # twice: the second starts from refit boxes
        moved = move(v, k)
        host.refit(moved)
        refit.run(moved)
        nodes = refit.read_nodes()
        assert np.array_equal(nodes.view(np.uint32), host.pack_nodes().view(np.uint32))
        assert np.array_equal(refit.read_triangles().view(np.uint32), host.pack_triangles().view(np.uint32))
        # and the boxes really moved with the geometry
        assert not np.array_equal(nodes, build_bvh(v, f, max_leaf_size=leaf).pack_nodes())


def test_traces_after_gpu_refit_match_a_rebuilt_bvh(gl):
    v, f = soup(1200, seed=12)
    gb = GpuBvh(gl, build_bvh(v, f))
    refit = GpuRefit(gl, gb)
    moved = move(v)
    refit.run(moved)
    o, d = rays_at(moved, 3000, seed=13)
    h = RayTracer(gl, gb).trace(o, d)
    ref = RayTracer(gl, GpuBvh(gl, build_bvh(moved, f))).trace(o, d)
    assert 0.3 < (ref.prim != MISS).mean() < 0.95
    frac, err = agreement(h.prim, h.t, ref.prim, ref.t, rel=0.0)   # same float32 test: exact
    assert frac == 1.0 and err == 0.0
    occ = RayTracer(gl, gb).trace(o, d, tmax=0.5, mode="any")
    assert np.array_equal(occ, RayTracer(gl, GpuBvh(gl, build_bvh(moved, f))).trace(o, d, tmax=0.5, mode="any"))


def test_gpu_refit_rejects_bad_input(gl):
    v, f = soup(50)
    gb = GpuBvh(gl, build_bvh(v, f))
    refit = GpuRefit(gl, gb)
    with pytest.raises(ValueError, match="NaN or inf"):
        bad = v.copy()
        bad[3, 1] = np.nan
        refit.run(bad)
    with pytest.raises(ValueError, match="needs 150 vertices"):
        refit.run(v[:10])
    with pytest.raises(ValueError, match="bvh2 layout"):
        GpuRefit(gl, GpuBvh(gl, build_bvh(v, f), layout="bvh4"))
    empty = GpuBvh(gl, build_bvh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64)))
    GpuRefit(gl, empty).run(np.zeros((0, 3), np.float32))   # nothing to do, no error
