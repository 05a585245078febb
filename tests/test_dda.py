"""The perspective-correct DDA screen-space tracer (glsl/ssrt/dda.glsl) against its numpy mirror
(rayvr/bench/tracers/dda.py trace_dda) and against an independent dense reference on planar scenes.

The dense reference (`dense_reference` below) walks the ray's straight line in screen space S in
0.02-pixel steps (built from two projected world points, not from the DDA's formulas) and tests
each sample against the *exact* plane of the surface its pixel shows: the brute-force single-layer
height field, to 0.02 px. The DDA approximates each pixel by its centre depth and tests one pixel
per column, so on planes its hits are off by at most a pixel or two except for grazing rays,
where a small depth error moves the crossing far along the ray (bounds below)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.bench.tracers.dda import HIT, NEAR, NONE, OFFSCREEN, DdaCamera, DdaTracer, read_linear_depth, trace_dda
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.renderer import Renderer
from rayvr.scene.loader import Material, from_arrays

SIZE = (64, 48)


class Frame:
    """A rendered frame's G-buffer with both tracers bound to it."""

    def __init__(self, r: Renderer, rig: StereoRig):
        r.render(rig)
        self.r, self.rig = r, rig
        self.gb = r.resource("gbuffer")
        self.eyes = rig.eyes()
        self.origin = r.scene.origin
        self.tracer = DdaTracer(r.gl)

    def cam(self, eye=0) -> DdaCamera:
        return DdaCamera.from_eye(self.eyes[eye], self.origin)

    def depth(self, eye=0):
        return read_linear_depth(self.gb, eye)

    def channel(self, name, eye=0):
        w, h = self.gb.size
        tex = self.gb.textures[name]
        dtype = np.float16 if name == "normal" else np.float32
        return np.frombuffer(tex.read(), dtype).reshape(self.gb.layers, h, w, -1)[eye].astype(np.float64)

    def gpu(self, o, d, eye=0, **kw):
        return self.tracer.trace(self.gb, self.eyes, self.origin, o, d, eye, **kw)

    def cpu(self, o, d, eye=0, **kw):
        return trace_dda(self.depth(eye), self.cam(eye), o, d, **kw)

    def free_space_rays(self, n, seed=0, eye=0):
        """Origins between the eye and the surface seen at random pixels (20-90 % of the way),
        random unit directions; scene-local."""
        rng = np.random.default_rng(seed)
        depth, pos = self.depth(eye), self.channel("position", eye)[..., :3]
        ys, xs = np.nonzero(depth > 0)
        pick = rng.integers(0, len(xs), n)
        cam = self.cam(eye)
        f = rng.uniform(0.2, 0.9, (n, 1))
        o = cam.position + f * (pos[ys[pick], xs[pick]] - cam.position)
        d = rng.normal(size=(n, 3))
        return o, d / np.linalg.norm(d, axis=1, keepdims=True)

    def reflection_rays(self, eye=0, offset=1e-3):
        """One mirror ray per covered pixel, from its G-buffer position pushed off by `offset`."""
        depth = self.depth(eye)
        ys, xs = np.nonzero(depth > 0)
        pos = self.channel("position", eye)[ys, xs, :3]
        n = self.channel("normal", eye)[ys, xs, :3]
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        v = pos - self.cam(eye).position
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        return pos + offset * n, v - 2 * (v * n).sum(1, keepdims=True) * n


def same(a, b):
    """Rays on which two DdaResults agree in status, pixel and steps."""
    return (a.status == b.status) & (a.steps == b.steps) & (a.pixel == b.pixel).all(1)


def finite(res):
    return np.isfinite(res.point).all()


# ----------------------------------------------------------------------------- scenes

def rig_looking_down_z(scale=1.0, near=None, fov=60.0):
    return StereoRig(Pose.look_at([0, 0, 0], [0, 0, -1]), ipd=0.064 * scale, fov_y=fov, size=SIZE,
                     near=0.05 * scale if near is None else near)


def tilted_plane(scale=1.0, dist=3.0, tilt=35.0):
    """A plane facing the eye at `dist`, turned by `tilt` degrees about x, filling the view.
    Returns the scene and its plane (point, unit normal), world."""
    a = math.radians(tilt)
    n = np.array([0.0, math.sin(a), math.cos(a)])
    c = np.array([0.0, 0.0, -dist]) * scale
    u, v = np.array([10.0 * dist, 0, 0]) * scale, np.array([0, math.cos(a), -math.sin(a)]) * 10 * dist * scale
    verts, faces = quad(c, u, v)
    return from_arrays(verts, faces, name="tilted"), [(c, n)]


def step(scale=1.0):
    """A step: a near slab (its edge near x = 0.3, turned 20 degrees about y) in front of a far
    wall, both facing the eye; a square hole in the wall (about 8 x 8 px) shows the background."""
    a = math.radians(20)
    back = merge(quad((-19.5, 0, -5), (20.5, 0, 0), (0, 40, 0)), quad((21, 0, -5), (19, 0, 0), (0, 40, 0)),
                 quad((1.5, -20.25, -5), (0.5, 0, 0), (0, 19.75, 0)), quad((1.5, 20.25, -5), (0.5, 0, 0), (0, 19.75, 0)))
    back = back[:2]   # the wall around a hole x in [1, 2], y in [-0.5, 0.5]
    front_c = np.array([-9.7, 0, -2.5])
    fu = np.array([10 * math.cos(a), 0, 10 * math.sin(a)])
    front = quad(front_c, fu, (0, 10, 0))
    front_n = np.cross(fu, [0, 10, 0])
    front_n /= np.linalg.norm(front_n)
    v, f, part = merge(back, front)
    scene = from_arrays(v * scale, f, triangle_material=part, materials=[Material("back"), Material("front")])
    return scene, [(np.array([0, 0, -5.0]) * scale, np.array([0, 0, 1.0])), (front_c * scale, front_n)]


# ------------------------------------------------------------------- dense reference

def plane_in_screen(cam: DdaCamera, point_world, normal, origin):
    """(alpha, beta, gamma): the plane's z = alpha x + beta y + gamma in S (float64)."""
    rot = cam.rotation.astype(np.float64)
    p_local = np.asarray(point_world, np.float64) - origin
    n_v = rot.T @ np.asarray(normal, np.float64)
    c_v = float(n_v @ (rot.T @ (p_local - cam.position.astype(np.float64))))
    l, r, b, t = cam.tangents.astype(np.float64)
    W, H = cam.size
    sx, sy = W / (r - l), H / (t - b)
    # view point (X, Y, -w) with X/w = l + x/sx, Y/w = b + y/sy; n_v . v = c_v; z = near / w
    k = cam.near / c_v
    return np.array([k * n_v[0] / sx, k * n_v[1] / sy, k * (n_v[0] * l + n_v[1] * b - n_v[2])])


def dense_reference(frame: Frame, planes, o, d, eye=0, spacing=0.02, chunk=256):
    """Brute-force height-field trace (see the module docstring): status, S hit point."""
    cam = frame.cam(eye)
    depth = frame.depth(eye).astype(np.float64)
    H, W = depth.shape
    coef = np.array([plane_in_screen(cam, p, n, frame.origin) for p, n in planes])  # (P, 3)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    zc = coef[:, 0, None, None] * xx + coef[:, 1, None, None] * yy + coef[:, 2, None, None]
    z_pix = np.where(depth > 0, cam.near / np.where(depth > 0, depth, 1), 0)
    which = np.argmin(np.abs(zc - z_pix) / np.maximum(z_pix, 1e-300), axis=0)  # the plane each pixel shows
    pa, pb, pc = coef[which, 0], coef[which, 1], coef[which, 2]
    o = np.asarray(o, np.float64)
    d = np.asarray(d, np.float64)
    n = len(o)
    status = np.zeros(n, np.int32)
    point = np.full((n, 3), np.nan)
    s0 = cam.to_screen(o)
    # a second point in front of the near plane gives the line's direction in S
    v_d = d @ cam.rotation.astype(np.float64)
    w0 = cam.near / s0[:, 2]
    dw = -v_d[:, 2]
    t1 = np.where(dw < 0, 0.5 * (w0 - cam.near) / np.maximum(-dw, 1e-300), 1.0 * w0)
    s1 = cam.to_screen(o + t1[:, None] * d)
    dirs = s1 - s0
    dirs /= np.maximum(np.abs(dirs[:, :2]).max(1), 1e-300)[:, None]   # unit major-axis steps
    steps = int(math.hypot(W, H) / spacing) + 2
    u = np.arange(1, steps + 1) * spacing
    for s in range(0, n, chunk):
        sl = slice(s, s + chunk)
        p = s0[sl, None, :] + u[None, :, None] * dirs[sl, None, :]   # (c, steps, 3)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        off = (x < 0) | (x >= W) | (y < 0) | (y >= H)
        near = z >= 1
        inf = z <= 0
        ix = np.clip(np.floor(x).astype(np.int64), 0, W - 1)
        iy = np.clip(np.floor(y).astype(np.int64), 0, H - 1)
        zs = pa[iy, ix] * x + pb[iy, ix] * y + pc[iy, ix]
        behind = (depth[iy, ix] > 0) & (z <= zs) & ~off & ~near & ~inf
        events = np.stack([behind, off, near, inf])
        first = np.where(events.any(2), events.argmax(2), steps)   # (4, c)
        kind = first.argmin(0)
        at = first.min(0)
        st = np.array([HIT, OFFSCREEN, NEAR, NONE])[kind]
        st[at >= steps] = NONE
        status[sl] = st
        rows = np.arange(len(at))
        point[sl] = p[rows, np.minimum(at, steps - 1)]
    return status, point


# ------------------------------------------------------------------------------ tests

def test_gpu_equals_numpy_in_the_room(gl):
    """Mirror rays from every covered pixel plus random rays, both eyes, strides 1 and 3, thin
    and solid pixels: the GPU and numpy marches agree ray for ray (measured on llvmpipe: all rays,
    bit for bit). On the H200 (2026-11-30), before the DDA_EDGE / DDA_BIAS tie rules, 97.9-99.2 %
    agreed at stride 1 (ties decided by rounding); with them all rays agree at 64x48 and 37x29,
    and 99.99 % (status: all) of 100k mirror rays at 1440x1600."""
    with Renderer(gl=gl) as r:
        for size in (SIZE, (37, 29)):   # and an odd size
            rig = StereoRig(Pose.look_at([0, 1.6, 3], [0, 1, 0]), size=size)
            fr = Frame(r, rig)
            for eye in (0, 1):
                o, d = fr.reflection_rays(eye)
                o2, d2 = fr.free_space_rays(1000, seed=eye, eye=eye)
                o, d = np.r_[o, o2], np.r_[d, d2]
                for stride, thickness in ((1, np.inf), (1, 0.05), (3, 0.02)):
                    kw = dict(max_steps=200, stride=stride, thickness=thickness)
                    g, c = fr.gpu(o, d, eye, **kw), fr.cpu(o, d, eye, **kw)
                    agree = same(g, c)
                    assert agree.mean() >= 0.995, (size, eye, stride, thickness, agree.mean())
                    assert np.abs(g.point - c.point)[agree].max() <= 1e-3
                    assert finite(g) and finite(c)
                    assert set(np.unique(g.status)) <= {HIT, OFFSCREEN, NEAR, NONE}
                    if thickness == np.inf:   # a closed room: most rays hit a wall
                        assert (g.status == HIT).mean() > 0.5
        timing = fr.tracer.time_trace(fr.gb, fr.eyes, fr.origin, o, d, 1, repeats=2)
        assert timing["rays"] == len(o) and timing["rays_per_s"] > 0 and timing["mean_steps"] > 1


def check_against_reference(fr, planes, o, d, eye=0, min_agree=0.99, bound_px=1.5, bound_share=0.98):
    """DDA (stride 1, enough steps, solid pixels) vs the dense reference: status agreement and
    hit point error in pixels. Returns (agreement, share of hits within bound_px, max error)."""
    g = fr.gpu(o, d, eye, max_steps=1000, stride=1, thickness=np.inf)
    c = fr.cpu(o, d, eye, max_steps=1000, stride=1, thickness=np.inf)
    assert same(g, c).mean() >= 0.995
    ref, ref_point = dense_reference(fr, planes, o, d, eye)
    agree = (g.status == ref).mean()
    both = (g.status == HIT) & (ref == HIT)
    err = np.linalg.norm(g.point[both, :2] - ref_point[both, :2], axis=1)
    within = (err <= bound_px).mean()
    assert finite(g)
    assert agree >= min_agree, (agree, np.c_[g.status, ref][g.status != ref][:10])
    assert within >= bound_share, (within, np.sort(err)[-10:])
    return agree, within, err.max() if len(err) else 0.0


@pytest.mark.parametrize("which", ["tilted", "step"])
def test_hits_agree_with_the_dense_reference(gl, which):
    """Random free-space rays: status agrees with the brute-force height field on >= 99 % of rays;
    >= 98 % of common hits lie within 1.5 px of the reference hit (the rest: grazing rays)."""
    scene, planes = tilted_plane() if which == "tilted" else step()
    with Renderer(scene, gl=gl) as r:
        fr = Frame(r, rig_looking_down_z())
        o, d = fr.free_space_rays(1500, seed=3)
        check_against_reference(fr, planes, o, d)


@pytest.mark.parametrize("scale, dist, near", [(1e-4, 3.0, None), (1e4, 3.0, None), (1.0, 1e3, 1e-4)])
def test_near_far_extremes(gl, scale, dist, near):
    """The tilted plane at 1e-4 and 1e4 scale (near scaled with it), and at 1e3 with near 1e-4
    (a near:distance ratio of 1e7): the same agreement and hit bounds as at scale 1, no NaN
    (z = near / depth is relative, and so is the pixels' thickness)."""
    scene, planes = tilted_plane(scale, dist)
    with Renderer(scene, gl=gl) as r:
        fr = Frame(r, rig_looking_down_z(scale, near))
        o, d = fr.free_space_rays(800, seed=5)
        check_against_reference(fr, planes, o, d)


def test_special_rays(gl):
    """Rays towards the camera, from near the near plane, leaving the screen, along the screen
    axes, straight into the screen; max_steps. Each: the status it must have, no NaN, GPU ==
    numpy."""
    scene, planes = tilted_plane()
    with Renderer(scene, gl=gl) as r:
        fr = Frame(r, rig_looking_down_z())
        cam = fr.cam()
        eye = cam.position.astype(np.float64)
        right, up, back = cam.rotation.astype(np.float64).T
        o, _ = fr.free_space_rays(200, seed=7)

        def run(o, d, **kw):
            g, c = fr.gpu(o, d, **kw), fr.cpu(o, d, **kw)
            assert same(g, c).all() and finite(g) and finite(c)
            return g

        # straight at the eye: a point on screen that reaches the near plane, no pixel tested
        to_eye = eye - o
        g = run(o, to_eye)
        assert (g.status == NEAR).all() and (g.steps == 0).all()
        # towards points beside the eye: through the near plane's window (NEAR) or past it
        # (OFFSCREEN), as the reference says
        aim = np.random.default_rng(8).uniform(-0.06, 0.06, (len(o), 2)) @ np.c_[right, up].T
        d = to_eye + aim
        g = run(o, d)
        ref, _ = dense_reference(fr, planes, o, d)
        assert set(np.unique(g.status)) <= {NEAR, OFFSCREEN} and (g.status == ref).mean() >= 0.99
        assert (g.status == NEAR).any() and (g.status == OFFSCREEN).any()
        # origins 1e-4 * near in front of the near plane: towards the eye NEAR at once, away ones hit
        o_near = eye - (1 + 1e-4) * cam.near * back + 1e-3 * cam.near * (right + up)
        g = run(np.repeat(o_near[None], 2, 0), np.array([back + 0.1 * right, -back + 0.1 * up]))
        assert g.status.tolist() == [NEAR, HIT]
        # in front of the near plane: moved onto it when going away (and then hits the plane),
        # NEAR without a step when not
        g = run(np.repeat((eye - 0.5 * cam.near * back + 0.01 * cam.near * up)[None], 3, 0),
                np.array([-back + 0.1 * right, back, right]))
        assert g.status.tolist() == [HIT, NEAR, NEAR] and g.steps.tolist()[1:] == [0, 0] and g.steps[0] > 0
        # straight into the screen from free space: the projection is a point; documented NONE, 0 steps
        g = run(o, o - eye)
        assert (g.status == NONE).all() and (g.steps == 0).all()
        # along the screen axes (parallel to the image plane), exactly and 1e-7 off; exactly
        # along an axis, a ray that leaves the screen tests each pixel up to the edge once
        s0 = cam.to_screen(o)
        W, H = SIZE
        for k, (axis, sign) in enumerate(((right, 1), (-right, -1), (up, 1), (-up, -1))):
            for wobble in (0.0, 1e-7, -1e-7):
                d = np.broadcast_to(axis + wobble * back, o.shape)
                g = run(o, d)
                ref, _ = dense_reference(fr, planes, o, d)
                assert (g.status == ref).mean() >= 0.98 and (g.steps > 0).mean() > 0.9
                if wobble == 0.0:
                    start = np.floor(s0[:, k // 2])
                    pixels_left = (SIZE[k // 2] - 1 - start) if sign > 0 else start
                    out = g.status == OFFSCREEN
                    assert out.sum() > 50 and (g.steps[out] == pixels_left[out]).all()
        # leaving the screen from the border pixels, outwards and through the corners
        border = np.array([[0.5, 24.5], [W - 0.5, 24.5], [32.5, 0.5], [32.5, H - 0.5], [0.5, 0.5], [W - 0.5, H - 0.5]])
        dirs2 = np.array([[-1, 0], [1, 0], [0, -1], [0, 1], [-1, -1], [1, 1]], float)
        l, rr, b, t = cam.tangents.astype(np.float64)
        for (px, py), (dx, dy) in zip(border, dirs2):
            ray = np.array([l + (rr - l) * px / W, b + (t - b) * py / H, -1.0]) @ cam.rotation.T.astype(np.float64)
            p = eye + 1.0 * ray       # 1 unit along the pixel's ray, in front of the plane
            g = run(p[None], (dx * right + dy * up)[None])
            assert g.status.tolist() == [OFFSCREEN] and g.steps[0] <= 1
        # max_steps: rays that hit far away run out of steps first
        d = np.broadcast_to(-up - 0.2 * back, o.shape)   # down and away: towards the plane
        full = run(o, d, max_steps=1000)
        cut = run(o, d, max_steps=3)
        far = (full.status == HIT) & (full.steps > 3)
        assert far.sum() > 20 and (cut.status[far] == NONE).all() and (cut.steps[far] == 3).all()
        assert (cut.status[full.steps <= 3] == full.status[full.steps <= 3]).all()


def test_background_and_infinity(gl):
    """A ray that runs to its vanishing point over background pixels ends NONE there (z = 0), and
    background pixels (linear_depth 0) are never hit."""
    verts, faces = quad((-3, 2, -6), (1, 0, 0), (0, 1, 0))   # a small square, top left
    with Renderer(from_arrays(verts, faces, name="square"), gl=gl) as r:
        fr = Frame(r, rig_looking_down_z())
        cam = fr.cam()
        eye = cam.position.astype(np.float64)
        right, up, back = cam.rotation.astype(np.float64).T
        assert (fr.depth() == 0).mean() > 0.8
        o = eye - 2 * back + np.array([[0.5, -0.3, 0], [0.7, 0.1, 0], [-0.6, -0.5, 0]]) @ np.c_[right, up, back].T
        g = fr.gpu(o, np.broadcast_to(-back, o.shape))
        c = fr.cpu(o, np.broadcast_to(-back, o.shape))
        assert same(g, c).all() and (g.status == NONE).all() and (g.steps > 3).all()
        assert np.allclose(g.point[:, :2], [SIZE[0] / 2, SIZE[1] / 2], atol=1.0)
        assert (np.abs(g.point[:, 2]) < 0.1 * cam.to_screen(o)[:, 2]).all()   # z near 0: the last pixel before infinity
        # random rays: hits only on the square's pixels
        o, d = fr.free_space_rays(500, seed=2)
        g = fr.gpu(o, d)
        hit = g.status == HIT
        assert hit.any() and (fr.depth()[g.pixel[hit, 1], g.pixel[hit, 0]] > 0).all()


def test_grazing_rays_need_a_bias_of_a_pixels_depth(gl):
    """Rays leaving the tilted plane at 2 and 10 degrees. The DDA compares the ray with each pixel's
    centre depth, so a ray that leaves its surface closer than the surface's depth change across a
    pixel (here ~0.035 units) hits the neighbouring pixel of its own surface (McGuire's
    self-intersection; measured: 92 % of 2-degree rays with a 1e-4 bias, 40 % at 10 degrees, all
    at the first steps). With the origin 0.1 off the surface (about 2 pixels' depth change) the
    statuses agree with the reference."""
    scene, planes = tilted_plane()
    n = planes[0][1]
    with Renderer(scene, gl=gl) as r:
        fr = Frame(r, rig_looking_down_z())
        depth, pos = fr.depth(), fr.channel("position")[..., :3]
        ys, xs = np.nonzero(depth > 0)
        p = pos[ys, xs][::3]
        rng = np.random.default_rng(0)
        for angle in (2.0, 10.0):
            t = rng.normal(size=p.shape)
            t -= (t @ n)[:, None] * n
            t /= np.linalg.norm(t, axis=1, keepdims=True)
            d = math.cos(math.radians(angle)) * t + math.sin(math.radians(angle)) * n
            close = fr.gpu(p + 1e-4 * n, d)
            assert finite(close) and (close.status == HIT).mean() > 0.3   # self-hits: the DDA's known fault
            o = p + 0.1 * n
            g = fr.gpu(o, d, max_steps=1000)
            ref, _ = dense_reference(fr, planes, o, d)
            assert finite(g) and (g.status == ref).mean() >= 0.99, (angle, (g.status == ref).mean())


def test_stride_trades_steps_for_error(gl):
    """Room mirror rays, stride 1, 2, 4, 8: the mean number of steps falls (about 1/stride), and
    both the rays lost (hit at stride 1, not at stride s) and the hit point error against stride 1
    grow. Measured (64x48): steps 18.5 / 9.6 / 4.9 / 2.7 with thickness 0.02, lost 0 / 6 / 13 /
    18 %; solid pixels: hit point error 0 / 0.3 / 0.9 / 1.8 px mean."""
    with Renderer(gl=gl) as r:
        fr = Frame(r, StereoRig(Pose.look_at([0, 1.6, 3], [0, 1, 0]), size=SIZE))
        o, d = fr.reflection_rays()
        for thickness in (0.02, np.inf):
            base = fr.gpu(o, d, max_steps=500, stride=1, thickness=thickness)
            steps, lost, err = [], [], []
            for s in (1, 2, 4, 8):
                g = fr.gpu(o, d, max_steps=500, stride=s, thickness=thickness)
                assert same(g, fr.cpu(o, d, max_steps=500, stride=s, thickness=thickness)).mean() >= 0.995
                both = (g.status == HIT) & (base.status == HIT)
                steps.append(g.steps.mean())
                lost.append(((base.status == HIT) & (g.status != HIT)).mean())
                err.append(np.linalg.norm(g.point[both, :2] - base.point[both, :2], axis=1).mean())
            assert all(a > 1.6 * b for a, b in zip(steps, steps[1:])), steps
            assert all(a < b for a, b in zip(err, err[1:])), err
            if thickness == 0.02:
                assert all(a < b for a, b in zip(lost, lost[1:])), lost


def heightfield_reference(fr: Frame, o, d, eye=0):
    """rayvr/accel/quadtree.py's brute-force tracer (every crossed pixel against its exact plane
    from the G-buffer position and its triangle's geometric normal): status, pixel, S point per ray."""
    from rayvr.accel import quadtree as qt

    cam = qt.ScreenCamera.from_eye(fr.eyes[eye], fr.origin)
    normal = qt.frame_geometric_normals(fr.gb, fr.r.scene)[eye]
    leaves = qt.build_reference(fr.channel("position", eye), normal, cam)[0]
    out = [qt.trace_heightfield_reference(leaves, cam, o[i], d[i]) for i in range(len(o))]
    return (np.array([t.status for t in out]), np.array([t.pixel for t in out]),
            np.array([t.point for t in out]))


ROOM_RIG = dict(pose=Pose.look_at([0, 1.6, 3], [0, 1, 0]), size=SIZE)


@pytest.mark.parametrize("scene, rays, min_agree, min_within", [
    ("room", "free", 0.98, 0.94), ("room", "mirror", 0.99, 0.96),
    ("tilted", "free", 0.995, 0.99), ("step", "free", 0.995, 0.99)])
def test_agrees_with_the_quadtree_brute_force(gl, scene, rays, min_agree, min_within):
    """Stride 1, 1000 steps, solid pixels (thickness inf: the reference's height field) against
    trace_heightfield_reference. Measured (600 rays, two seeds): status agreement room 98.5-98.7 %
    (free-space rays) / 99.5 % (mirror rays from the G-buffer), tilted plane 99.7-99.8 %, step
    100 %; common hits within 1.5 px: room 95-96 % / 97-98 %, planes 100 % (median 0.2 / 0.04 /
    0.1 / 0.0 px; max 1.5 px on the planes, 25 px in the room). The rest are the DDA's
    approximations: one pixel per column at its centre depth, so rays that graze a surface or
    pass a pixel's corner differ (the room's objects are a few pixels wide at 64x48)."""
    if scene == "room":
        sc, rig = None, StereoRig(**ROOM_RIG)
    else:
        sc = (tilted_plane() if scene == "tilted" else step())[0]
        rig = rig_looking_down_z()
    with Renderer(sc, gl=gl) as r:
        fr = Frame(r, rig)
        if rays == "free":
            o, d = fr.free_space_rays(600, seed=11)
        else:
            o, d = fr.reflection_rays()
            pick = np.random.default_rng(0).choice(len(o), 600, replace=False)
            o, d = o[pick], d[pick]
        g = fr.gpu(o, d, max_steps=1000, stride=1, thickness=np.inf)
        status, pixel, point = heightfield_reference(fr, o, d)
        agree = (g.status == status).mean()
        both = (g.status == HIT) & (status == HIT)
        err = np.linalg.norm(g.point[both, :2] - point[both, :2], axis=1)
        assert finite(g) and both.sum() > 100
        assert agree >= min_agree, agree
        assert (err <= 1.5).mean() >= min_within, np.percentile(err, [50, 90, 99])
