"""The screen-space quadtree (rayvr/accel/quadtree.py, glsl/ssrt/quadtree*.glsl): the numpy
brute-force height-field tracer is the reference; the numpy stackless traversal and the GPU's
must return what it returns on lossless trees; the GPU build must equal the numpy build."""
import math

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.accel import quadtree as qt
from rayvr.camera import Pose, StereoRig
from rayvr.passes.quadtree import QuadtreePass, QuadtreeTracer
from rayvr.renderer import Renderer
from rayvr.scene import from_arrays

SIZE = (37, 29)  # not a power of two, odd both ways


def sphere(center, radius, n=24):
    """A UV sphere (verts, faces), smooth enough for the G-buffer's shading normals."""
    th, ph = np.meshgrid(np.linspace(0, np.pi, n // 2 + 1), np.linspace(0, 2 * np.pi, n + 1), indexing="ij")
    v = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1).reshape(-1, 3)
    f = []
    cols = n + 1
    for i in range(n // 2):
        for j in range(n):
            a, b, c, d = i * cols + j, i * cols + j + 1, (i + 1) * cols + j, (i + 1) * cols + j + 1
            f += [[a, c, b], [b, c, d]]
    return np.asarray(center, float) + radius * v, np.array(f)


def scenes():
    """Analytic scenes: (name, scene, rig)."""
    out = {}
    rig = StereoRig(Pose.look_at([0, 0.6, 1.0], [0, 0, -4]), ipd=0.1, fov_y=60, size=SIZE)
    v, f = quad((0, 0, -4), (3, 0, 0), (0, 2.5, 2.0))
    out["tilted_plane"] = (from_arrays(v, f), rig)
    v, f, _ = merge(quad((0, 0, -5), (4, 0, 0), (0, 4, 0)), quad((-1.5, 0, -3), (1.2, 0, 0), (0, 3, 0)))
    out["step"] = (from_arrays(v, f), rig)
    v, f, _ = merge(quad((0, 0, -6), (6, 0, 0), (0, 6, 0)), sphere((0.2, 0.1, -3.5), 1.0))
    out["sphere"] = (from_arrays(v, f), rig)
    v, f, _ = merge(quad((0, 0, -5), (4, 0, 0), (0, 4, 0)), quad((0.3, 0, -3), (0.02, 0, 0), (0, 3, 0)))
    out["thin_pole"] = (from_arrays(v, f), rig)
    return out


class Layers:
    """A rendered frame's G-buffer channels (rows bottom-up, GL order) and the eyes' cameras."""

    def __init__(self, gl, scene, rig):
        self.renderer = Renderer(scene, gl=gl)
        self.renderer.render(rig, aux=())
        gb = self.renderer.resource("gbuffer")
        w, h = rig.size
        self.position = np.frombuffer(gb.textures["position"].read(), np.float32).reshape(2, h, w, 4).copy()
        self.normal = np.frombuffer(gb.textures["normal"].read(), np.float16).reshape(2, h, w, 4).astype(np.float32)
        self.cams = [qt.ScreenCamera.from_eye(e, self.renderer.scene.origin) for e in rig.eyes()]
        self.scene, self.rig = scene, rig

    def build(self, layer=0, **gammas):
        return qt.build_reference(self.position[layer], self.normal[layer], self.cams[layer], **gammas)

    def tracer(self, **gammas):
        """The GPU tree of this frame (QuadtreeTracer), built with `gammas`."""
        if not hasattr(self, "_tracer"):
            self._tracer = QuadtreeTracer(self.renderer)
        self._tracer.build(self.rig, **gammas)
        return self._tracer

    def release(self):
        if hasattr(self, "_tracer"):
            self._tracer.release()
        self.renderer.release()


def random_rays(rng, layers: Layers, layer: int, n: int):
    """Rays that mostly meet geometry: from points lifted off random surface pixels (or from
    random points in front of the eye) towards other surface pixels, with jitter; and a share of
    arbitrary directions."""
    cam = layers.cams[layer]
    pos = layers.position[layer].reshape(-1, 4)
    nor = layers.normal[layer].reshape(-1, 4)[:, :3]
    geo = np.nonzero(pos[:, 3] > 0)[0]
    a, b = rng.choice(geo, n), rng.choice(geo, n)
    lift = rng.uniform(0.02, 0.6, (n, 1))
    o = pos[a, :3] + lift * nor[a]
    free = rng.random(n) < 0.3
    fwd = -cam.rotation[:, 2]
    o[free] = cam.position + fwd * rng.uniform(0.3, 2.0, (free.sum(), 1)) + rng.normal(0, 0.3, (free.sum(), 3))
    d = pos[b, :3] - o + rng.normal(0, 0.15, (n, 3))
    wild = rng.random(n) < 0.2
    d[wild] = rng.normal(0, 1, (wild.sum(), 3))
    return o.astype(np.float64), d.astype(np.float64)


def same(a: qt.Trace, b: qt.Trace, tol=1e-6) -> bool:
    if a.status != b.status:
        return False
    if a.status != qt.HIT:
        return True
    return a.pixel == b.pixel and np.allclose(a.point, b.point, rtol=tol, atol=tol)


@pytest.fixture(scope="module")
def analytic(gl):
    out = {name: Layers(gl, s, r) for name, (s, r) in scenes().items()}
    yield out
    for x in out.values():
        x.release()


# ------------------------------------------------------------------ host side, no traversal

def test_level_sizes_any_image_size():
    assert qt.level_sizes(37, 29) == [(37, 29), (19, 15), (10, 8), (5, 4), (3, 2), (2, 1), (1, 1)]
    assert qt.level_sizes(1, 1) == [(1, 1)]
    assert qt.level_sizes(64, 48)[-2:] == [(2, 2), (1, 1)]
    offs, n = qt.level_offsets(qt.level_sizes(37, 29))
    assert offs[:3] == [0, 37 * 29, 37 * 29 + 19 * 15] and n == sum(w * h for w, h in qt.level_sizes(37, 29))
    assert qt.quadtree_bytes(37, 29, 2) == 2 * 8 * n


def test_node_encoding_round_trips():
    z0 = np.array([1.0, 1e-7, 0.5, 3.0e-3])
    sx, sy = np.array([0.0, -0.25, 1e-3, 7.0]), np.array([1e-5, 0.5, -2.0, 0.0])
    d = qt.decode(qt.encode_planes(z0, sx, sy, [0, 1, 0, 1]))
    assert d.plane.all() and list(d.flag) == [False, True, False, True]
    assert np.allclose(d.z0, z0, rtol=2.4e-7)                       # 1 ulp: the flag bit
    assert np.allclose(d.sx, sx, rtol=2 ** -11, atol=6e-8) and np.allclose(d.sy, sy, rtol=2 ** -11, atol=6e-8)
    b = qt.decode(qt.encode_aabbs([0.0, 0.2], [0.0, 0.7], [1, 0]))
    assert not b.plane.any() and list(b.flag) == [True, False]
    assert b.zmin[0] == 0 and 0 < np.float32(0.2) - b.zmin[1] <= 1.5e-8    # cleared flag bit: rounds down
    assert list(b.zmax) == [0.0, np.float32(0.7)]


def test_leaf_planes_are_exact_on_a_tilted_plane(analytic):
    """z of a pixel's leaf at its neighbours' centres equals their z (the plane is one plane in
    S); the half-float slopes keep that within 2^-11 x the z change."""
    L = analytic["tilted_plane"]
    d = qt.decode(L.build()[0])
    both = d.plane[:, :-1] & d.plane[:, 1:]
    assert both.sum() > 300
    z0, z1, sx = d.z0[:, :-1][both], d.z0[:, 1:][both], d.sx[:, :-1][both]
    err = np.abs(z0 * (1 + sx) - z1) / z1      # the left pixel's plane one pixel right
    change = np.abs(z1 - z0) / z1
    assert (err <= 2 ** -11 * change + 1e-6).all(), err.max()


def test_aabbs_bound_their_leaves(analytic):
    """Every AABB's [zmin, zmax] holds the z range of each leaf below it (odd size: no row or
    column dropped)."""
    L = analytic["sphere"]
    levels = L.build()
    W, H = SIZE
    X0, X1, Y0, Y1 = qt.node_rects(0, SIZE)
    leaf = qt.decode(levels[0], (X1 - X0) / 2, (Y1 - Y0) / 2)
    for k in range(1, len(levels)):
        n = qt.decode(levels[k])
        for qy in range(levels[k].shape[0]):
            for qx in range(levels[k].shape[1]):
                ys, xs = slice(qy << k, min((qy + 1) << k, H)), slice(qx << k, min((qx + 1) << k, W))
                assert not n.plane[qy, qx]
                assert n.zmax[qy, qx] >= leaf.zmax[ys, xs].max()
                assert n.zmin[qy, qx] <= leaf.zmin[ys, xs].min()


# ------------------------------------------------------------------ numpy traversal vs brute force

@pytest.mark.parametrize("name", ["tilted_plane", "step", "sphere", "thin_pole"])
def test_numpy_quadtree_equals_brute_force(analytic, name):
    L = analytic[name]
    rng = np.random.default_rng(7)
    stats = {s: 0 for s in qt.STATUS_NAMES}
    for layer in (0, 1):
        levels = L.build(layer)
        o, d = random_rays(rng, L, layer, 60)
        for i in range(len(o)):
            a = qt.trace_heightfield_reference(levels[0], L.cams[layer], o[i], d[i])
            b = qt.trace_quadtree_reference(levels, L.cams[layer], o[i], d[i])
            assert same(a, b), (name, layer, i, a, b)
            assert np.isfinite(a.point).all()
            stats[a.status] += 1
    assert stats[qt.HIT] >= 40, stats   # the rays do meet the geometry


# ------------------------------------------------------------------ GPU build and traversal

LOSSLESS = dict(gamma_norm=1.0, gamma_dist=0.0)
LOSSY = dict(gamma_norm=math.cos(math.radians(10)), gamma_dist=1e-3)


def assert_same_tree(gpu_levels, ref_levels):
    """Node for node: the same kinds and flags; z values to float32 rounding (GPU division and
    the numpy build's float64 then rounded); slopes to one half-float step."""
    for k, (g, r) in enumerate(zip(gpu_levels, ref_levels)):
        a, b = qt.decode(g), qt.decode(r)
        assert (a.plane == b.plane).all(), f"level {k}: {(a.plane != b.plane).sum()} nodes differ in kind"
        assert (a.flag == b.flag).all(), f"level {k}: {(a.flag != b.flag).sum()} discontinuity flags differ"
        for v in ("z0", "zmin", "zmax"):
            x, y = getattr(a, v), getattr(b, v)
            assert np.allclose(x, y, rtol=2e-6, atol=0), (k, v, np.abs(x - y).max())
        for v in ("sx", "sy"):
            x, y = getattr(a, v), getattr(b, v)
            assert np.allclose(x, y, rtol=2 ** -10, atol=1e-7), (k, v, np.abs(x - y).max())


@pytest.mark.parametrize("gammas", [LOSSLESS, LOSSY], ids=["lossless", "lossy"])
@pytest.mark.parametrize("name", ["sphere", "step"])
def test_gpu_build_equals_numpy_build(analytic, name, gammas):
    L = analytic[name]
    tr = L.tracer(**gammas)
    for layer in (0, 1):
        assert_same_tree(tr.levels(layer), L.build(layer, **gammas))
    if gammas is LOSSY:  # the thresholds do merge: the sphere's and the walls' planes
        assert sum(qt.decode(lv).plane.sum() for lv in tr.levels(0)[1:]) > 20


def gpu_traces(tracer, o, d, layer):
    st, nodes, pix, pt = tracer.trace(o, d, layer)
    return [qt.Trace(int(st[i]), tuple(int(v) for v in pix[i]), pt[i].astype(np.float64), int(nodes[i]))
            for i in range(len(o))]


def check_against_brute_force(L, o, d, layer, tol=1e-4, rate=1.0, gammas=LOSSLESS):
    """GPU and numpy quadtree traces against the brute force on the GPU-built lossless tree:
    the same status, and on hits the same pixel and point within `tol` (relative, per component;
    float32 on the GPU). Returns the brute-force traces."""
    tracer = L.tracer(**gammas)
    levels = tracer.levels(layer)
    gpu = gpu_traces(tracer, o, d, layer)
    ref, agree = [], 0
    for i in range(len(o)):
        a = qt.trace_heightfield_reference(levels[0], L.cams[layer], o[i], d[i])
        b = qt.trace_quadtree_reference(levels, L.cams[layer], o[i], d[i])
        assert same(a, b), (i, a, b)                 # numpy traversal: float64, exactly the same
        assert np.isfinite(gpu[i].point).all() and np.isfinite(a.point).all()
        agree += same(a, gpu[i], tol)
        ref.append(a)
    assert agree >= rate * len(o), f"GPU agrees with the brute force on {agree}/{len(o)} rays"
    return ref, gpu


@pytest.mark.parametrize("name", ["tilted_plane", "step", "sphere", "thin_pole"])
def test_gpu_quadtree_equals_brute_force(analytic, name):
    L = analytic[name]
    rng = np.random.default_rng(11)
    for layer in (0, 1):
        o, d = random_rays(rng, L, layer, 80)
        ref, gpu = check_against_brute_force(L, o, d, layer)
        assert sum(t.status == qt.HIT for t in ref) > 30


def test_default_room(gl):
    rig = StereoRig(Pose.look_at([0.3, 1.5, 2.6], [0, 0.8, 0]), ipd=0.064, fov_y=80, size=(48, 36))
    L = Layers(gl, None, rig)
    try:
        rng = np.random.default_rng(5)
        for layer in (0, 1):
            o, d = random_rays(rng, L, layer, 80)
            ref, gpu = check_against_brute_force(L, o, d, layer)
            assert sum(t.status == qt.HIT for t in ref) > 40
            assert_same_tree(L.tracer(**LOSSY).levels(layer), L.build(layer, **LOSSY))
    finally:
        L.release()
