"""The pinhole: rays from the eye through the pixel centres of the planar frustum given by the
eye's tangents. These are exactly the rays the rasterizer samples (same tangents as the eye's
projection matrix), so it is the one rasterizable model. GLSL: glsl/cameras/pinhole.glsl."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import CameraModel, CameraRays


@dataclass(frozen=True)
class Pinhole(CameraModel):
    name = "pinhole"
    rasterizable = True
    glsl = "cameras/pinhole.glsl"

    def check_rig(self, rig) -> None:
        # A plane in front of the eye spans less than 180 degrees; wider views need a
        # non-planar (spherical) model.
        if not (0 < rig.fov_y < 180):
            raise ValueError(f"fov_y must be in (0, 180) degrees for a planar projection, got {rig.fov_y}")

    def rays(self, eye, channel: int = 0) -> CameraRays:
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
