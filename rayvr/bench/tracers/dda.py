"""Perspective-correct DDA screen-space ray marching (McGuire & Mara 2014): the baseline the
quadtree tracer is measured against. Two implementations of the same steps:

- `trace_dda(...)`: numpy, float32, vectorised over rays; it mirrors glsl/ssrt/dda.glsl line for
  line, so the GPU and numpy results agree ray for ray (status, pixel, steps) up to float rounding
  where the ray passes exactly over a pixel edge or a depth;
- `DdaTracer(gl)`: traces a batch on the GPU through glsl/ssrt/dda_batch.comp against the G-buffer
  of a rendered frame (`Renderer.resource("gbuffer")`), for tests and benchmarks.

Screen space S of one eye layer: (x, y, z), x and y in pixels (GL: origin bottom-left, pixel
centres at +0.5), z = near / view_depth (reversed-Z, 1 at the near plane, 0 at infinity). S is a
projective image of view space, so a ray is a straight line in S and z is linear along it: marching
the line in S *is* McGuire & Mara's interpolation of 1/w-scaled quantities.

The march, for a ray (scene-local origin o, direction d) of eye e:
1. View space: v0 = R^T (o - eye_position), dv = R^T d; w = -v.z (view depth). An origin closer
   than the near plane (w0 < near) moves along the ray onto it (McGuire's near clip); if the ray
   does not go away from the eye it never enters the frustum: NEAR without a step.
2. The line in S: S(u) = S0 + u D with D = (hd_xy - S0_xy dw, -z0 dw) (hd: the direction's
   homogeneous screen coordinates, dw = -dv.z); u = t / w(t) along the ray. It ends at infinity
   (z = 0, u = 1/dw) for rays going away, at the near plane (z = 1, u = (w0 - near) / (-dw near))
   for rays coming towards the camera (McGuire's near clip, done analytically), never for rays
   parallel to the image plane.
3. Clip the line to the viewport [0, W] x [0, H]: u in [u_lo, u_hi]. Empty: OFFSCREEN.
4. Step along the major screen axis: sample k is the column (row) centre c_k = col0 + 0.5 +
   sign * k * stride; it tests the pixel the line passes at c_k against the ray's z interval over
   [c_k - stride/2, c_k + stride/2] (clipped to the segment). With stride 1 the interval is the
   line's whole span in that column, so no depth between columns is skipped; a larger stride skips
   columns (fewer steps, more misses). The first sample is the column after the origin's (the
   origin is taken to lie on the surface its pixel shows: a reflection ray); a ray entering from
   off screen or through the near plane starts with the column it enters.
5. Depth test (single-layer height field): a pixel with geometry (linear_depth > 0) has surface
   z_s = near / linear_depth and is `thickness` thick *relative to its depth*: it occupies view
   depths [d, d (1 + thickness)], z in [z_s / (1 + thickness), z_s]. The ray hits when its z
   interval over the step overlaps that slab. thickness = inf makes every pixel a solid height
   field (a ray that passes behind any surface hits it). A relative thickness keeps the test the
   same at every scale (near 1e-4 or 1e7).
   Ties: a ray that leaves through the side it marches towards ends exactly on a column
   boundary, and rays from pixel centres with simple slopes cross pixel edges exactly at column
   centres; so that float rounding (which differs between drivers) decides none of them, a column
   is tested only if the segment reaches EDGE = 1/256 px into it, and the pixel is picked BIAS =
   1/256 px further along the ray than the sample.
6. Result: HIT (pixel, the point on the line where its z reaches z_s, clamped to the step's
   interval), OFFSCREEN (the line left the viewport), NEAR (it reached the near plane), NONE
   (max_steps tests without a hit, or the line ran to infinity, z = 0, on screen). `pixel` and
   `point` are those of the last test when there is no hit ((-1, -1) and the origin when no test
   was made); `steps` counts the pixels tested.

A ray whose screen projection never leaves its origin's column (straight into or out of the
screen) tests nothing: NONE going away, NEAR coming towards the camera. (The brute-force
reference, rayvr/accel/quadtree.py trace_heightfield_reference, does test the origin's pixel:
the two differ on rays from free space whose hit lies in the origin's column.)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import moderngl
import numpy as np

from ...gl import shaders
from ...accel.gpu import WARMUP_S
from ...accel.quadtree import HIT, NEAR, NONE, OFFSCREEN, dispatch_per_ray, pack_screen_rays
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO
# declare constants the screen-space shaders read (CAMERA_*, SHARED_CHANNEL)
from ...frame import graph  # noqa: F401
from ...frame.cameras import base as camera_models  # noqa: F401
from ...gl.timing import time_gpu

EDGE = declare("DDA_EDGE", np.float32(1.0 / 256.0))  # a column is tested if the segment reaches this far (px) into it
BIAS = declare("DDA_BIAS", np.float32(1.0 / 256.0))  # the pixel is picked this far (px) along the ray from the sample
STATUS_NAMES = {HIT: "hit", OFFSCREEN: "offscreen", NEAR: "near", NONE: "none"}

f32 = np.float32


@dataclass(frozen=True)
class DdaCamera:
    """One eye's camera as the shaders see it (float32, scene-local): the values of
    glsl/common/camera.glsl's uniforms for that eye, and the image size."""

    position: np.ndarray  # (3,) scene-local eye position
    rotation: np.ndarray  # (3, 3) camera-to-world (columns right, up, back)
    tangents: np.ndarray  # (4,) left, right, bottom, top
    near: float
    size: tuple  # (W, H)

    @classmethod
    def from_eye(cls, eye, origin) -> "DdaCamera":
        """From a rayvr.frame.cameras.rig.EyeView and the scene's origin (what the GPU's uniforms hold)."""
        u = eye.camera.uniforms([eye], origin)
        return cls(u["eye_position"][0].copy(), u["eye_rotation"][0].T.copy(), u["eye_tangents"][0].copy(),
                   float(f32(eye.near)), tuple(eye.size))

    def to_screen(self, points) -> np.ndarray:
        """Scene-local points in front of the near plane -> S (x, y, z), float64 (for tests)."""
        p = np.atleast_2d(np.asarray(points, np.float64))
        v = (p - self.position.astype(np.float64)) @ self.rotation.astype(np.float64)
        w = -v[:, 2]
        l, r, b, t = self.tangents.astype(np.float64)
        W, H = self.size
        return np.c_[(v[:, 0] / w - l) / (r - l) * W, (v[:, 1] / w - b) / (t - b) * H, self.near / w]


class DdaResult(NamedTuple):
    status: np.ndarray  # (N,) int32: HIT, OFFSCREEN, NEAR, NONE
    pixel: np.ndarray   # (N, 2) int32 (x, y), GL rows (0 = bottom); (-1, -1) when no pixel was tested
    point: np.ndarray   # (N, 3) float32 S point (x, y, z) of the hit (else of the last test)
    steps: np.ndarray   # (N,) int32 pixels tested


def thickness_factor(thickness: float) -> np.float32:
    """1 / (1 + thickness): the far side of a pixel's slab in z is z_s * this (0 for inf)."""
    return f32(0.0) if np.isinf(thickness) else f32(1.0) / (f32(1.0) + f32(thickness))


def trace_dda(linear_depth, cam: DdaCamera, origins, directions, max_steps: int = 256, stride: float = 1.0,
              thickness: float = np.inf) -> DdaResult:
    """The numpy DDA (the module docstring says what each step does).

    linear_depth: (H, W) view depth per pixel in GL row order (row 0 = bottom; as the G-buffer
    texture reads back), 0 = background. origins, directions: (N, 3) scene-local."""
    depth = np.asarray(linear_depth, f32)
    H, W = depth.shape
    if (W, H) != tuple(cam.size):
        raise ValueError(f"depth is {W}x{H} but the camera's image is {cam.size[0]}x{cam.size[1]}")
    if not stride >= 1.0:
        raise ValueError(f"stride must be >= 1 pixel, got {stride}")
    o = np.asarray(origins, f32).reshape(-1, 3)
    d = np.asarray(directions, f32).reshape(-1, 3)
    n = len(o)
    near = f32(cam.near)
    l, r, b, t = (f32(x) for x in cam.tangents)
    size = np.array([W, H], f32)
    sx, sy = size[0] / (r - l), size[1] / (t - b)
    kthick = thickness_factor(thickness)
    stride = f32(stride)
    half = stride * f32(0.5)

    # 1. view space (rotation^T (o - p), as `(o - p) * eye_rotation` in GLSL)
    rot = np.asarray(cam.rotation, f32)
    rel = o - np.asarray(cam.position, f32)
    v0 = np.stack([rel[:, 0] * rot[0, k] + rel[:, 1] * rot[1, k] + rel[:, 2] * rot[2, k] for k in range(3)], 1)
    dv = np.stack([d[:, 0] * rot[0, k] + d[:, 1] * rot[1, k] + d[:, 2] * rot[2, k] for k in range(3)], 1)
    w0, dw = -v0[:, 2], -dv[:, 2]
    clipped = ~(w0 >= near)  # also NaN
    behind = clipped & ~(dw > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = np.where(clipped & ~behind, (near - w0) / np.where(behind, f32(1.0), dw), f32(0.0))
    v0 = np.where(clipped[:, None], v0 + ts[:, None] * dv, v0)
    w0s = np.where(clipped, near, w0)

    # 2. the line in S
    s0 = np.stack([(v0[:, 0] / w0s - l) * sx, (v0[:, 1] / w0s - b) * sy, near / w0s], 1)
    hd = np.stack([(dv[:, 0] - l * dw) * sx, (dv[:, 1] - b * dw) * sy], 1)
    D = np.stack([hd[:, 0] - s0[:, 0] * dw, hd[:, 1] - s0[:, 1] * dw, -s0[:, 2] * dw], 1)
    inf = f32(np.inf)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        u_end = np.where(dw > 0, f32(1.0) / np.where(dw > 0, dw, f32(1.0)),
                         np.where(dw < 0, (w0s - near) / (np.where(dw < 0, -dw, f32(1.0)) * near), inf))
        end_status = np.where(dw < 0, NEAR, NONE)

        # 3. clip to the viewport
        u_lo = np.zeros(n, f32)
        u_hi = u_end.copy()
        outside = np.zeros(n, bool)
        for k in range(2):
            dk = D[:, k]
            safe = np.where(dk != 0, dk, f32(1.0))
            ua = (f32(0.0) - s0[:, k]) / safe
            ub = (size[k] - s0[:, k]) / safe
            lo, hi = np.minimum(ua, ub), np.maximum(ua, ub)
            moving = dk != 0
            u_lo = np.where(moving, np.maximum(u_lo, lo), u_lo)
            screen_hi = np.where(moving, hi, inf)
            end_status = np.where(screen_hi < u_hi, OFFSCREEN, end_status)
            u_hi = np.minimum(u_hi, screen_hi)
            outside |= ~moving & ((s0[:, k] < 0) | (s0[:, k] > size[k]))
        outside |= ~(u_lo < u_hi)

        # 4. march setup: unit step along the major axis
        m = np.maximum(np.abs(D[:, 0]), np.abs(D[:, 1]))
        degenerate = ~(m > 0)
        ms = np.where(degenerate, f32(1.0), m)
        Dn = D / ms[:, None]
        major = np.where(np.abs(D[:, 0]) >= np.abs(D[:, 1]), 0, 1)
        # the clipped segment spans at most the image along the major axis (a guard against overflow)
        a_hi = np.where(degenerate, f32(0.0), np.minimum((u_hi - u_lo) * m, size[major]))
        s_lo = s0 + u_lo[:, None] * D
    idx = np.arange(n)
    x_lo = s_lo[idx, major]
    sgn = np.where(Dn[idx, major] < 0, f32(-1.0), f32(1.0))
    col0 = np.where(sgn > 0, np.floor(x_lo), np.ceil(x_lo) - f32(1.0))
    k = np.where((u_lo > 0) | clipped, 0, 1).astype(f32)

    status = np.where(behind, NEAR, np.where(outside, OFFSCREEN, 0)).astype(np.int32)
    pixel = np.full((n, 2), -1, np.int32)
    point = s0.astype(f32)
    steps = np.zeros(n, np.int32)
    active = status == 0
    for _ in range(int(max_steps) + 1):
        if not active.any():
            break
        a = np.flatnonzero(active)
        out_of_steps = steps[a] >= max_steps
        status[a[out_of_steps]] = NONE
        a = a[~out_of_steps]
        c = col0[a] + f32(0.5) + sgn[a] * k[a] * stride
        ak = (c - x_lo[a]) * sgn[a]
        a_start = np.maximum(ak - half, f32(0.0))
        ended = ~(a_start + EDGE < a_hi[a])
        status[a[ended]] = end_status[a[ended]]
        a, ak, a_start = a[~ended], ak[~ended], a_start[~ended]
        a_end = np.minimum(ak + half, a_hi[a])
        ap = np.minimum(ak, a_hi[a])
        p = s_lo[a, :2] + ap[:, None] * Dn[a, :2] + BIAS * np.sign(Dn[a, :2])
        px = np.clip(np.floor(p).astype(np.int64), 0, [W - 1, H - 1]).astype(np.int32)
        pixel[a] = px
        point[a] = s_lo[a] + ap[:, None] * Dn[a]
        steps[a] += 1
        k[a] += f32(1.0)
        za = s_lo[a, 2] + a_start * Dn[a, 2]
        zb = s_lo[a, 2] + a_end * Dn[a, 2]
        zmin, zmax = np.minimum(za, zb), np.maximum(za, zb)
        ld = depth[px[:, 1], px[:, 0]]
        zs = near / np.where(ld > 0, ld, f32(1.0))
        hit = (ld > 0) & (zmin <= zs) & (zmax >= zs * kthick)
        h = a[hit]
        if len(h):
            dz = Dn[h, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                across = np.where(dz != 0, (zs[hit] - s_lo[h, 2]) / np.where(dz != 0, dz, f32(1.0)), a_start[hit])
            ah = np.minimum(np.maximum(across, a_start[hit]), a_end[hit])
            point[h] = s_lo[h] + ah[:, None] * Dn[h]
            status[h] = HIT
        active[:] = status == 0
    return DdaResult(status, pixel, point, steps)


class DdaTracer:
    """Traces ray batches with glsl/ssrt/dda_batch.comp against a rendered frame's G-buffer.

        r.render(rig); gb = r.resource("gbuffer")
        res = DdaTracer(r.gl).trace(gb, rig.eyes(), r.scene.origin, origins, directions, eye=0)
    """

    def __init__(self, gl):
        self.ctx: moderngl.Context = getattr(gl, "ctx", gl)
        self.program = shaders.compute(self.ctx, "ssrt/dda_batch.comp")

    def trace(self, gbuffer, eyes, scene_origin, origins, directions, eye=0, max_steps: int = 256,
              stride: float = 1.0, thickness: float = np.inf) -> DdaResult:
        """`eyes`: the frame's EyeViews (index = G-buffer layer); `eye`: the layer of each ray
        (an int or (N,) ints); origins and directions scene-local (world - scene_origin)."""
        if not stride >= 1.0:
            raise ValueError(f"stride must be >= 1 pixel, got {stride}")
        prog = self.program
        for name, value in eyes[0].camera.uniforms(list(eyes), scene_origin).items():
            if shaders.declares(prog, name):
                prog[name].write(np.ascontiguousarray(value).tobytes())
        rays = pack_screen_rays(origins, directions, eye)
        n = len(rays)
        if n == 0:
            z = np.zeros(0, np.int32)
            return DdaResult(z, np.zeros((0, 2), np.int32), np.zeros((0, 3), f32), z)
        prog["ray_count"].value = n
        prog["max_steps"].value = int(max_steps)
        prog["stride"].value = float(stride)
        prog["thickness_factor"].value = float(thickness_factor(thickness))
        gbuffer.bind_for_reading()
        rbuf = self.ctx.buffer(rays.tobytes())
        obuf = self.ctx.buffer(reserve=n * 32)
        try:
            rbuf.bind_to_storage_buffer(SSBO["dda_rays"])
            obuf.bind_to_storage_buffer(SSBO["dda_results"])
            dispatch_per_ray(prog, n)
            self.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)
            out = np.frombuffer(obuf.read(), np.uint32).reshape(n, 8)
        finally:
            rbuf.release()
            obuf.release()
        status = out[:, 0].astype(np.int32)
        steps = out[:, 1].astype(np.int32)
        pixel = out[:, 2:4].view(np.int32).copy()
        point = out[:, 4:7].view(f32).copy()
        return DdaResult(status, pixel, point, steps)

    def time_trace(self, gbuffer, eyes, scene_origin, origins, directions, eye=0, max_steps: int = 256,
                   stride: float = 1.0, thickness: float = np.inf, repeats: int = 10) -> dict:
        """GPU ms per dispatch of the batch (rays already on the GPU; timing.time_gpu: the median of
        5 timed batches once the times settle), rays/s and the mean steps per ray."""
        res = self.trace(gbuffer, eyes, scene_origin, origins, directions, eye, max_steps, stride, thickness)
        rays = pack_screen_rays(origins, directions, eye)
        n = len(rays)
        rbuf = self.ctx.buffer(rays.tobytes())
        obuf = self.ctx.buffer(reserve=max(n, 1) * 32)
        try:
            gbuffer.bind_for_reading()
            rbuf.bind_to_storage_buffer(SSBO["dda_rays"])
            obuf.bind_to_storage_buffer(SSBO["dda_results"])
            t = time_gpu(self.ctx, lambda: dispatch_per_ray(self.program, n), repeats, WARMUP_S)
        finally:
            rbuf.release()
            obuf.release()
        return {"rays": n, "gpu_ms": t["gpu_ms"], "gpu_ms_min": t["gpu_ms_min"], "gpu_ms_max": t["gpu_ms_max"],
                "wall_ms": t["wall_ms"], "rays_per_s": n / (t["ms"] * 1e-3), "mean_steps": float(res.steps.mean()),
                "max_steps_reached": float((res.steps >= max_steps).mean())}

    def release(self) -> None:
        self.program.release()


def read_linear_depth(gbuffer, layer: int = 0) -> np.ndarray:
    """(H, W) float32 view depth of one G-buffer layer, GL row order (row 0 = bottom)."""
    w, h = gbuffer.size
    data = np.frombuffer(gbuffer.textures["linear_depth"].read(), f32).reshape(gbuffer.layers, h, w)
    return data[layer].copy()


__all__ = ["trace_dda", "DdaTracer", "DdaCamera", "DdaResult", "read_linear_depth",
           "thickness_factor", "HIT", "OFFSCREEN", "NEAR", "NONE", "STATUS_NAMES"]
