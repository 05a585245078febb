"""Hi-Z screen-space tracing: a min-max depth pyramid and its hierarchical traversal, the second
baseline beside the DDA (rayvr/bench/tracers/dda.py) for the quadtree (rayvr/accel/quadtree.py).

Screen space S, statuses (HIT, OFFSCREEN, NEAR, NONE) and the projection of a ray (quadtree.py
`screen_ray`) are those of the quadtree. The surface is the single-layer height field of the
G-buffer's `linear_depth`, one z = near / depth per pixel (constant over the pixel, as the DDA
sees it; the quadtree's leaves are planes): a ray hits the first pixel where it passes below that
z (strictly), with infinite thickness by default or a relative thickness as in dda.py (a pixel is
the slab z in [z / (1 + thickness), z]).

Pyramid (glsl/ssrt/hiz_build.comp): level k has ceil(W/2^k) x ceil(H/2^k) cells (the quadtree's
level_sizes), each (zmin, zmax) of its pixels' z, float32; background pixels (depth 0) count in
neither: a cell with no geometry is (EMPTY, 0). Stored in an SSBO, layer after layer, levels
finest first, row-major (8 bytes a cell).

Traversal (glsl/ssrt/hiz.glsl hiz_trace, mirrored by `trace_hiz_reference`): start on
`start_level` in the cell holding the ray's first point on screen; visit a cell: the ray's z over
[u, exit] (exit: the first far wall) against [zmin * factor, zmax]; overlap: move u to where the
ray enters that slab and go down a level (level 0: HIT); miss: step across the wall that comes
first (one axis only) and go up a level. Cells are integer indices, u only ever moves to walls
computed by one formula, and which child holds p(u) is decided in u, so no float position is
nudged. `iterations` counts cells visited; `max_iterations` reached is NONE. `skip_origin`
starts where the ray leaves its origin's pixel (as the DDA skips the origin's column): for
reflection rays, whose flat origin pixel would stop them wherever the surface recedes.

`HizTracer(renderer)`: builds the pyramid of the renderer's last frame and traces ray batches
on the GPU (glsl/ssrt/hiz_batch.comp), with the interface of rayvr/frame/passes/quadtree.py
QuadtreeTracer (build, trace, time).
"""
from __future__ import annotations

from typing import NamedTuple

import moderngl
import numpy as np

from ...gl import shaders
from ...accel.quadtree import (HIT, INF, NEAR, NONE, OFFSCREEN, ScreenCamera, Trace, encode_aabbs, encode_planes,
                               level_offsets, level_sizes, screen_ray, set_level_uniforms, time_build_and_trace,
                               trace_screen_rays)
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO
# declare constants the screen-space shaders read (CAMERA_*, SHARED_CHANNEL)
from ...frame import graph  # noqa: F401
from ...frame.cameras import base as camera_models  # noqa: F401

STATUS_NAMES = {HIT: "hit", OFFSCREEN: "offscreen", NEAR: "near", NONE: "none"}
EMPTY = declare("HIZ_EMPTY", np.float32(3.0e38))  # zmin of a cell without geometry (finite: EMPTY * 0 is 0, not NaN)
START_LEVEL = 2              # default first level of the walk (any level gives the same result)
MAX_ITERATIONS = 1024        # default cap on cells visited per ray
LOCAL = declare("HIZ_BUILD_LOCAL", 8)  # hiz_build.comp's local size (x and y)
f32 = np.float32


def hiz_bytes(width: int, height: int, layers: int) -> int:
    return 8 * level_offsets(level_sizes(width, height))[1] * layers


def thickness_factor(thickness: float) -> float:
    """1 / (1 + thickness), 0 for infinite thickness (as rayvr/bench/tracers/dda.py)."""
    return 0.0 if np.isinf(thickness) else float(f32(1.0) / (f32(1.0) + f32(thickness)))


# ------------------------------------------------------------------ numpy references

def pyramid_reference(linear_depth, near: float) -> list[np.ndarray]:
    """The min-max pyramid of one layer: (h_k, w_k, 2) float32 (zmin, zmax) per level, finest
    first. linear_depth: (H, W), GL row order (row 0 = bottom), 0 = background."""
    depth = np.asarray(linear_depth, f32)
    geo = depth > 0
    z = f32(near) / np.where(geo, depth, f32(1.0))
    levels = [np.stack([np.where(geo, z, EMPTY), np.where(geo, z, f32(0.0))], -1).astype(f32)]
    while levels[-1].shape[:2] != (1, 1):
        levels.append(pyramid_reference_level(levels[-1]))
    return levels


def pyramid_reference_level(cells: np.ndarray) -> np.ndarray:
    """The next coarser level of (h, w, 2) (zmin, zmax) cells: ceil(w/2) x ceil(h/2) cells."""
    hc, wc = cells.shape[:2]
    hk, wk = (hc + 1) // 2, (wc + 1) // 2
    # pad to (2 hk, 2 wk) with cells that change nothing, then reduce 2 x 2 blocks
    pad = np.empty((2 * hk, 2 * wk, 2), f32)
    pad[..., 0], pad[..., 1] = EMPTY, 0.0
    pad[:hc, :wc] = cells
    blocks = pad.reshape(hk, 2, wk, 2, 2)
    return np.stack([blocks[..., 0].min(axis=(1, 3)), blocks[..., 1].max(axis=(1, 3))], -1)


def flat_leaves(linear_depth, near: float) -> np.ndarray:
    """Level-0 quadtree nodes (H, W, 2) of the same height field as the pyramid (planes of slope 0
    at z = near / depth; background AABB [0, 0]): what quadtree.py trace_heightfield_reference
    takes, so the brute force traces exactly the surface the Hi-Z walk sees (to 1 ulp of z: the
    node format keeps a flag in z's lowest bit)."""
    depth = np.asarray(linear_depth, f32)
    geo = depth > 0
    z = f32(near) / np.where(geo, depth, f32(1.0))
    zero = np.zeros_like(z)
    return np.where(geo[..., None], encode_planes(z, zero, zero, 0), encode_aabbs(zero, zero, 0))


def trace_hiz_reference(levels, cam: ScreenCamera, origin, direction, start_level: int = START_LEVEL,
                        max_iterations: int = MAX_ITERATIONS, thickness: float = np.inf,
                        skip_origin: bool = False) -> Trace:
    """The walk of glsl/ssrt/hiz.glsl hiz_trace, step for step, in float64 (`Trace.nodes` holds
    the iterations). `levels`: pyramid_reference's list (or the GPU's, read back)."""
    ray = screen_ray(cam, origin, direction)
    if ray.u_lo > ray.u_hi:
        return Trace(ray.end, (-1, -1), ray.s0, 0)
    W, H = cam.size
    top = len(levels) - 1
    factor = thickness_factor(thickness)
    s0, sd = ray.s0, ray.sd

    def wall(axis, c):
        return (c - s0[axis]) / sd[axis] if sd[axis] != 0 else INF

    k = min(max(int(start_level), 0), top)
    u = ray.u_lo
    if skip_origin and u == 0 and not _moved_to_near(cam, origin, direction):
        px = [float(np.floor(s0[0])), float(np.floor(s0[1]))]
        for i in (0, 1):
            if sd[i] < 0 and s0[i] == px[i]:
                px[i] -= 1.0
        u = max(min(wall(0, px[0] + 1 if sd[0] > 0 else px[0]), wall(1, px[1] + 1 if sd[1] > 0 else px[1])), u)
        if u >= ray.u_hi:
            return Trace(ray.end, (-1, -1), s0 + ray.u_hi * sd if ray.u_hi < INF else s0, 0)
    p = s0 + u * sd
    q = [int(np.floor(p[0])) >> k, int(np.floor(p[1])) >> k]
    for i in (0, 1):
        if sd[i] < 0 and p[i] == float(q[i] << k) and q[i] > 0:
            q[i] -= 1
    q = [min(max(q[0], 0), levels[k].shape[1] - 1), min(max(q[1], 0), levels[k].shape[0] - 1)]
    it = 0
    while it < max_iterations:
        it += 1
        lo = (q[0] << k, q[1] << k)
        hi = (min(lo[0] + (1 << k), W), min(lo[1] + (1 << k), H))
        ux = wall(0, hi[0] if sd[0] > 0 else lo[0])
        uy = wall(1, hi[1] if sd[1] > 0 else lo[1])
        u_exit = max(min(ux, uy), u)
        ub = min(u_exit, ray.u_hi)
        zmin, zmax = (float(v) for v in levels[k][q[1], q[0]])
        slab_lo, slab_hi = zmin * factor, zmax
        za, zb = s0[2] + u * sd[2], s0[2] + ub * sd[2]
        if ub > u and min(za, zb) < slab_hi and max(za, zb) >= slab_lo:
            ue = u
            if za >= slab_hi:
                ue = (slab_hi - s0[2]) / sd[2]
            elif za < slab_lo:
                ue = (slab_lo - s0[2]) / sd[2]
            u = min(max(ue, u), ub)
            if k == 0:
                return Trace(HIT, (q[0], q[1]), s0 + u * sd, it)
            c = []
            for i in (0, 1):
                mid = float((2 * q[i] + 1) << (k - 1))
                if sd[i] > 0:
                    c.append(1 if u >= wall(i, mid) else 0)
                elif sd[i] < 0:
                    c.append(0 if u >= wall(i, mid) else 1)
                else:
                    c.append(1 if s0[i] >= mid else 0)
            k -= 1
            q = [min(2 * q[0] + c[0], levels[k].shape[1] - 1), min(2 * q[1] + c[1], levels[k].shape[0] - 1)]
            continue
        if u_exit >= ray.u_hi:
            break
        u = u_exit
        if ux <= uy:
            q[0] += 1 if sd[0] > 0 else -1
        else:
            q[1] += 1 if sd[1] > 0 else -1
        if not (0 <= q[0] < levels[k].shape[1] and 0 <= q[1] < levels[k].shape[0]):
            break
        if k < top:
            k += 1
            q = [q[0] >> 1, q[1] >> 1]
    else:
        return Trace(NONE, (-1, -1), s0 + u * sd, it)
    return Trace(ray.end, (-1, -1), s0 + ray.u_hi * sd if ray.u_hi < INF else s0, it)


def _moved_to_near(cam: ScreenCamera, origin, direction) -> bool:
    """Whether screen_ray moved the origin onto the near plane (hiz.glsl HizRay.moved)."""
    o = cam.rotation.T @ (np.asarray(origin, np.float64) - cam.position)
    d = cam.rotation.T @ np.asarray(direction, np.float64)
    return bool(-d[2] > 0 and (cam.near + o[2]) / -d[2] > 0)


# ------------------------------------------------------------------ GPU

def set_hiz_uniforms(program, size) -> None:
    """hiz_level, hiz_top, hiz_layer_cells of glsl/ssrt/hiz.glsl for an eye image of `size`."""
    set_level_uniforms(program, size, "hiz", "hiz_layer_cells")


class HizResult(NamedTuple):
    status: np.ndarray      # (N,) uint32: HIT, OFFSCREEN, NEAR, NONE
    iterations: np.ndarray  # (N,) uint32 cells visited
    pixel: np.ndarray       # (N, 2) int32 GL pixel of the hit, (-1, -1) otherwise
    point: np.ndarray       # (N, 3) float32 in S


class HizTracer:
    """Builds the min-max pyramid of a renderer's last frame and traces ray batches through it on
    the GPU; the interface of rayvr/frame/passes/quadtree.py QuadtreeTracer.

        tracer = HizTracer(renderer)
        renderer.render(rig, aux=())
        tracer.build(rig)
        status, iterations, pixel, point = tracer.trace(origins, directions, eye=0)
    """

    def __init__(self, renderer):
        self.renderer = renderer
        self.ctx: moderngl.Context = renderer.gl.ctx
        self.build_program = shaders.compute(self.ctx, "ssrt/hiz_build.comp")
        self.program = shaders.compute(self.ctx, "ssrt/hiz_batch.comp")
        self.cells: moderngl.Buffer | None = None
        self.size = None
        self.layers = 0
        self._eye_values = None

    def build(self, rig, eyes: str = "both") -> None:
        """Build the pyramid of the last rendered frame (rendered with `rig` and `eyes`)."""
        gbuffer = self.renderer.resource("gbuffer")
        views = rig.eyes(eyes)
        self._eye_values = views[0].camera.uniforms(views, self.renderer.scene.origin)
        nbytes = hiz_bytes(*gbuffer.size, gbuffer.layers)
        if self.cells is None or self.cells.size != nbytes:
            if self.cells is not None:
                self.cells.release()
            self.cells = self.ctx.buffer(reserve=nbytes)
        self.size, self.layers = tuple(gbuffer.size), gbuffer.layers
        self._run_build(gbuffer)
        self.ctx.finish()

    def _run_build(self, gbuffer) -> None:
        prog = self.build_program
        self._set_eyes(prog)
        set_hiz_uniforms(prog, self.size)
        gbuffer.bind_for_reading()
        self.cells.bind_to_storage_buffer(SSBO["hiz_levels"])
        for k, (wk, hk) in enumerate(level_sizes(*self.size)):
            prog["hiz_build_level"].value = k
            prog.run((wk + LOCAL - 1) // LOCAL, (hk + LOCAL - 1) // LOCAL, self.layers)
            self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)  # level k + 1 reads it

    def _set_eyes(self, program) -> None:
        for name, value in self._eye_values.items():
            if shaders.declares(program, name):
                program[name].write(np.ascontiguousarray(value).tobytes())

    def levels(self, layer: int = 0) -> list[np.ndarray]:
        """The built pyramid of one layer, read back: (h_k, w_k, 2) float32 per level, finest first."""
        sizes = level_sizes(*self.size)
        offs, per_layer = level_offsets(sizes)
        flat = np.frombuffer(self.cells.read(), f32).reshape(-1, 2)[layer * per_layer:(layer + 1) * per_layer]
        return [flat[o:o + w * h].reshape(h, w, 2).copy() for o, (w, h) in zip(offs, sizes)]

    def _bind(self, rbuf, obuf, n, start_level, max_iterations, thickness, skip_origin) -> None:
        prog = self.program
        set_hiz_uniforms(prog, self.size)
        self._set_eyes(prog)
        self.cells.bind_to_storage_buffer(SSBO["hiz_levels"])
        rbuf.bind_to_storage_buffer(SSBO["hiz_rays"])
        obuf.bind_to_storage_buffer(SSBO["hiz_results"])
        prog["ray_count"].value = n
        prog["start_level"].value = int(start_level)
        prog["max_iterations"].value = int(max_iterations)
        prog["thickness_factor"].value = thickness_factor(thickness)
        prog["skip_origin"].value = bool(skip_origin)

    def trace(self, origins, directions, eye=0, start_level: int = START_LEVEL,
              max_iterations: int = MAX_ITERATIONS, thickness: float = np.inf,
              skip_origin: bool = False) -> HizResult:
        """Trace scene-local rays in layer `eye` (an int or one per ray). skip_origin: start where
        each ray leaves its origin's pixel (reflection rays, as the DDA does)."""
        out = trace_screen_rays(
            self.ctx, self.program, origins, directions, eye,
            lambda rbuf, obuf, n: self._bind(rbuf, obuf, n, start_level, max_iterations, thickness, skip_origin))
        return HizResult(out[:, 0].copy(), out[:, 1].copy(), out[:, 2:4].view(np.int32).copy(),
                         out[:, 4:7].view(f32).copy())

    def time(self, rig, origins, directions, eye=0, start_level: int = START_LEVEL,
             max_iterations: int = MAX_ITERATIONS, thickness: float = np.inf, skip_origin: bool = False,
             repeats: int = 10, min_seconds: float = 1.0) -> dict:
        """As QuadtreeTracer.time: GPU ms of the build (all levels, all layers) and of tracing the
        rays (already on the GPU), after the times settle (timing.settle); median of 5 batches of
        `repeats` each; wall time per dispatch where llvmpipe's timer reads ~0. Adds the mean
        iterations per ray and the share of rays that ran out of them."""
        gbuffer = self.renderer.resource("gbuffer")
        self.build(rig, "both" if gbuffer.layers == 2 else "left")
        res = self.trace(origins, directions, eye, start_level, max_iterations, thickness, skip_origin)
        out = time_build_and_trace(
            self.ctx, self.program, origins, directions, eye, lambda: self._run_build(gbuffer),
            lambda rbuf, obuf, n: self._bind(rbuf, obuf, n, start_level, max_iterations, thickness, skip_origin),
            repeats, min_seconds)
        n = out["rays"]
        out["mean_iterations"] = float(res.iterations.mean()) if n else 0.0
        out["max_iterations_reached"] = float((res.iterations >= max_iterations).mean()) if n else 0.0
        return out

    def release(self) -> None:
        self.build_program.release()
        self.program.release()
        if self.cells is not None:
            self.cells.release()


__all__ = ["HIT", "OFFSCREEN", "NEAR", "NONE", "STATUS_NAMES", "EMPTY", "hiz_bytes", "pyramid_reference", "pyramid_reference_level",
           "flat_leaves", "trace_hiz_reference", "set_hiz_uniforms", "HizTracer", "HizResult", "thickness_factor"]
