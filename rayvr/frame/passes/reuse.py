"""Stereo `reuse` (photon-mapping paper §3.3, rayvr/frame/stereo.py): the left eye's shading given to the
right-eye pixels that see the same surface, for every effect.

    reuse_map   (glsl/stereo/reuse_map.comp) projects every left-eye hit into the right eye; where
                the right eye's G-buffer shows the same surface there (visibility test), the hit
                lands on that pixel (the nearest landing to the pixel's centre wins); writes
                "reuse_map"
    classify, shade
                read "reuse_map" under this mode (STEREO_REUSE, glsl/stereo/reuse.glsl) and skip the
                taken right-eye pixels: only the right-eye pixels left empty are listed and shaded
    reuse_copy  (glsl/stereo/reuse_copy.comp) reads the finished "hdr" (after every effect composed
                its pixels) and composes the taken right-eye pixels from their left-eye pixels

`reference_map` is the numpy reference of the map, from the two eyes' G-buffer channels.
"""
from __future__ import annotations

import moderngl
import numpy as np

from ...gl import shaders
from ..graph import Buffer, FramePlan, Pass, compose, read, write
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import IMAGE, NO_HIT, SSBO
from .compute import TILE, camera_defines, set_eye_uniforms

REUSE_NONE = declare("REUSE_NONE", 0xFFFFFFFF, uint=True)  # reuse_map: the right eye shades the pixel itself
TOLERANCE = 0.01  # tangent-plane distance a right-eye pixel may be from the left hit, x view depth
REUSE_MAP = Buffer(lambda s: 8 * s.size[0] * s.size[1], "8 B per eye pixel: source left pixel, nearest landing")


def stereo_reuse(plan: FramePlan) -> bool:
    return plan.stereo == "reuse" and plan.eyes == 2


def reuse_reads(plan: FramePlan) -> list:
    """What a shading pass (classify, shade) reads under `reuse` so that it skips the taken pixels."""
    return [read("reuse_map")] if stereo_reuse(plan) else []


def reuse_defines(plan: FramePlan) -> dict:
    return {"STEREO_REUSE": 1} if stereo_reuse(plan) else {}


def bind_reuse(fc) -> None:
    if stereo_reuse(fc.plan):
        fc.resource("reuse_map").bind_to_storage_buffer(SSBO["reuse_map"])


def reuse_counts(fc) -> dict:
    """Right-eye pixels that took a left-eye pixel's shading in frame `fc` (reads back)."""
    w, h = fc.gbuffer.size
    m = np.frombuffer(fc.resource("reuse_map").read(), np.uint32)[:w * h]
    return {"reused": int((m != REUSE_NONE).sum()), "right_pixels": w * h}


def read_map(fc) -> np.ndarray:
    """The reuse map of frame `fc`: (H, W) int64, rows top-down, the left pixel's flat index in
    the same top-down layout (y * W + x), -1 where the right eye shades its own pixel."""
    w, h = fc.gbuffer.size
    m = np.frombuffer(fc.resource("reuse_map").read(), np.uint32)[:w * h].reshape(h, w)[::-1].astype(np.int64)
    x, y_gl = m % w, m // w
    return np.where(m == REUSE_NONE, -1, (h - 1 - y_gl) * w + x)


def reference_map(left, right, eye_left, eye_right, tolerance: float = TOLERANCE) -> np.ndarray:
    """numpy reference of reuse_map.comp from the eyes' images (EyeImage with aux position,
    normal, material; rows top-down) and their EyeViews: (H, W) int64 as `read_map` returns."""
    h, w = left.depth.shape
    hit = left.aux["triangle"] != NO_HIT
    p = left.aux["position"].astype(np.float64)
    n = left.aux["normal"].astype(np.float64)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    v = (p - eye_right.position) @ eye_right.rotation  # world -> right eye's view axes
    depth = -v[..., 2]
    ok = hit & (depth > eye_right.near)
    depth = np.where(ok, depth, 1.0)
    l_, r_, b_, t_ = eye_right.tangents
    fx = (v[..., 0] / depth - l_) / (r_ - l_) * w
    fy = (v[..., 1] / depth - b_) / (t_ - b_) * h  # GL rows (up)
    ok &= (fx >= 0) & (fx < w) & (fy >= 0) & (fy < h)
    rx, ry = np.floor(np.where(ok, fx, 0)).astype(np.int64), np.floor(np.where(ok, fy, 0)).astype(np.int64)
    d2 = (fx - rx - 0.5) ** 2 + (fy - ry - 0.5) ** 2
    ok &= ((n * (eye_right.position - p)).sum(-1) > 0)
    rrow = h - 1 - ry  # top-down row of the landing
    q_tri = right.aux["triangle"][rrow, rx]
    q_mat = right.aux["material"][rrow, rx]
    q_pos = right.aux["position"][rrow, rx].astype(np.float64)
    ok &= (q_tri != NO_HIT) & (q_mat == left.aux["material"])
    ok &= np.abs(((q_pos - p) * n).sum(-1)) <= tolerance * depth
    out = np.full(h * w, -1, np.int64)
    best = np.full(h * w, np.inf)
    ys, xs = np.nonzero(ok)
    # GL index order of the left pixel breaks ties (the shader's atomicMin on x + y_gl * W).
    gl_index = (h - 1 - ys) * w + xs
    target = rrow[ys, xs] * w + rx[ys, xs]
    dist = d2[ys, xs].astype(np.float32)  # the shader compares float32 distances
    for k in np.lexsort((gl_index, dist)):
        t = target[k]
        if best[t] == np.inf:
            best[t] = dist[k]
            out[t] = ys[k] * w + xs[k]
    return out.reshape(h, w)


class ReuseMapPass(Pass):
    name = "reuse_map"
    timed_kernels = True

    def __init__(self, tolerance: float = TOLERANCE):
        self.tolerance = tolerance

    def why(self, plan: FramePlan) -> str | None:
        return "stereo = reuse" if stereo_reuse(plan) and plan.view == "color" else None

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), write("reuse_map", REUSE_MAP)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.programs = {k: shaders.compute(gl.ctx, "stereo/reuse_map.comp", {"REUSE_STAGE": i, **camera_defines(plan)})
                         for i, k in enumerate(("clear", "nearest", "owner"))}

    def execute(self, fc) -> None:
        fc.gbuffer.bind_for_reading()
        bind_reuse(fc)
        w, h = fc.gbuffer.size
        for name, p in self.programs.items():
            set_eye_uniforms(p, fc)
            if shaders.declares(p, "reuse_tolerance"):
                p["reuse_tolerance"].value = self.tolerance

            def go(p=p):
                p.run((w + TILE - 1) // TILE, (h + TILE - 1) // TILE, 1)
                fc.gl.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
            fc.stage(name, go)

    def release(self) -> None:
        for p in self.programs.values():
            p.release()


class ReuseCopyPass(Pass):
    name = "reuse_copy"

    def why(self, plan: FramePlan) -> str | None:
        return "stereo = reuse" if stereo_reuse(plan) and plan.view == "color" else None

    def io(self, plan: FramePlan) -> list:
        # Reads the finished hdr (after every composer), then overwrites the taken right-eye pixels.
        return [read("reuse_map"), read("hdr"), compose("hdr")]

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "stereo/reuse_copy.comp")

    def execute(self, fc) -> None:
        bind_reuse(fc)
        fc.resource("hdr").bind_to_image(IMAGE["hdr"], read=True, write=True)
        w, h = fc.gbuffer.size
        self.program.run((w + TILE - 1) // TILE, (h + TILE - 1) // TILE, 1)
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()
