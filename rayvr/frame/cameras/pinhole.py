"""The pinhole: rays from the eye through the pixel centres of the planar frustum given by the
eye's tangents. These are exactly the rays the rasterizer samples (same tangents as the eye's
projection matrix), so it is the one rasterizable model. GLSL: glsl/cameras/pinhole.glsl."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .base import CAMERA_MODELS, CameraModel, CameraRays, normalize, planar_transforms_fields

# Largest frustum tangent (x / -z at an image edge) the pinhole takes. Beyond it float32 clip
# coordinates (raster) and pixel-ray directions (rays) lose the pixel and the two primary
# visibility paths stop agreeing. Measured on the default room, triangle IDs of both paths, both
# eyes, fov_y and one-sided HMD rigs, llvmpipe and an NVIDIA GPU at 160x120 to 1440x1600: >= 99.99 %
# of pixels agree up to 1e5, 99.6 % at 1.5e5, 98.3-99.0 % from 2e5 on. 1e5 is 179.9989 degrees.
MAX_TANGENT = 1e5
# Smallest step of the frustum tangent from one pixel to the next. Float32 resolves directions to
# ~1.2e-7 of their length and raster clip coordinates to as little, so below it neighbouring
# pixels merge: rays land on the wrong triangle, the raster leaves holes and wrong depths, and
# steps below 1.2e-38 flush to zero (a blank frame). Measured on the default room looking at a
# mesh vertex, 64x48, triangle IDs against a float64 numpy trace: both paths >= 99.8 % right at a
# step of 3.6e-7, raster 98 % and rays 99 % at 1.1e-7, rays 17 % at 3.6e-10 (fov_y 1e-6 degrees).
MIN_PIXEL_TANGENT = 1e-6


def planar_directions(eye, x, y) -> np.ndarray:
    """World unit directions through GL image positions (x, y) of the eye's planar frustum."""
    w, h = eye.size
    l, r, b, t = eye.tangents
    v = np.stack(np.broadcast_arrays(l + np.asarray(x) / w * (r - l), b + np.asarray(y) / h * (t - b), -1.0), axis=-1)
    return normalize(v @ eye.rotation.T)


def _wide_angle_advice() -> str:
    wide = [name for name, model in CAMERA_MODELS.items() if model.wide_angle]
    return (f"use a wide-angle camera model ({', '.join(wide)})" if wide else
            "wider views need a wide-angle camera model, which this rayvr does not have yet")


def check_planar_rig(rig) -> None:
    """Refuse a rig whose eyes' planar frusta float32 cannot project: fov_y of 180 degrees and
    more, tangents past MAX_TANGENT, pixels narrower than MIN_PIXEL_TANGENT (ValueError)."""
    # A plane in front of the eye spans less than 180 degrees, and near 180 its float32
    # clip coordinates and pixel rays lose the pixel (see MAX_TANGENT).
    if not (0 < rig.fov_y < 180):
        raise ValueError(f"fov_y must be in (0, 180) degrees for a planar projection, got {rig.fov_y}; "
                         f"{_wide_angle_advice()}")
    for eye in rig.eyes():
        tangents = eye.tangents
        if len(tangents) != 4 or not all(math.isfinite(x) for x in tangents):
            raise ValueError(f"{eye.name} eye: frustum tangents must be 4 finite numbers, got {tangents}")
        own = bool(rig.eye_tangents and eye.name in rig.eye_tangents)
        worst = max(abs(x) for x in tangents)
        if worst > MAX_TANGENT:
            if own:
                what = f"eye_tangents[{eye.name!r}] reach {worst:.4g}"
            else:  # tangents scale with tan(fov_y / 2) = tangents[3]
                limit = math.degrees(2 * math.atan(tangents[3] * MAX_TANGENT / worst))
                what = (f"fov_y {rig.fov_y} on a {rig.size[0]}x{rig.size[1]} image reaches frustum tangent "
                        f"{worst:.4g} (fov_y {limit:.5f} at most here)")
            raise ValueError(f"{what}; planar projection precision ends at tangent {MAX_TANGENT:.0e}: raster and "
                             f"ray-cast visibility disagree beyond it; {_wide_angle_advice()}")
        l, r, b, t = tangents
        step = min((r - l) / eye.size[0], (t - b) / eye.size[1])
        if step < MIN_PIXEL_TANGENT:
            if own:
                what = f"eye_tangents[{eye.name!r}] {tuple(tangents)} make pixels of tangent {step:.3g}"
            else:  # square pixels: the vertical step is 2 tan(fov_y / 2) / height
                least = math.degrees(2 * math.atan(MIN_PIXEL_TANGENT * eye.size[1] / 2))
                what = (f"fov_y {rig.fov_y:g} on a {rig.size[0]}x{rig.size[1]} image makes pixels of tangent "
                        f"{step:.3g} (fov_y {least:.3g} degrees at least here)")
            raise ValueError(f"{what}; float32 rays and raster resolve pixels down to a tangent of "
                             f"{MIN_PIXEL_TANGENT:.0e}")


@dataclass(frozen=True)
class Pinhole(CameraModel):
    name = "pinhole"
    rasterizable = True
    judged_by_pinhole = True  # the reference itself
    glsl = "cameras/pinhole.glsl"

    def check_rig(self, rig) -> None:
        check_planar_rig(rig)

    def transforms_fields(self, eye) -> dict:
        return planar_transforms_fields(eye)

    def ray_at(self, eye, channel, x, y, lens):
        d = planar_directions(eye, x, y)
        return np.asarray(eye.position, np.float64), d, np.ones(d.shape[:-1], bool)

    def rays(self, eye, channel: int = 0, subsample=None) -> CameraRays:
        if subsample is not None:  # sub-rays: the generic path (finite-difference footprints)
            return super().rays(eye, channel, subsample)
        self._check_channel(channel)
        w, h = eye.size
        l, r, b, t = eye.tangents
        # Pixel centres on the plane z = -1 (eye space), rows top-down.
        xs = l + (np.arange(w) + 0.5) / w * (r - l)
        ys = t - (np.arange(h) + 0.5) / h * (t - b)
        v = np.stack(np.broadcast_arrays(xs[None, :], ys[:, None], -np.ones((h, w))), axis=-1)
        v = v @ eye.rotation.T
        length = np.linalg.norm(v, axis=-1, keepdims=True)
        d = v / length
        # d = v/|v| gives dd = (I - d d^T) dv / |v|; one pixel moves v by a constant step.
        step_x = eye.rotation[:, 0] * ((r - l) / w)
        step_y = eye.rotation[:, 1] * (-(t - b) / h)  # one row down
        ddx = (step_x - d * (d @ step_x)[..., None]) / length
        ddy = (step_y - d * (d @ step_y)[..., None]) / length
        origins = np.broadcast_to(np.asarray(eye.position, np.float64), (h, w, 3))
        return CameraRays(origins, d, ddx, ddy, np.ones((h, w), bool))
