"""An orthographic camera, a model from outside rayvr (tests/test_camera_plugin.py registers it):
parallel rays along each eye's view axis, from the points of a `height`-tall image plane through
the eye (width: height x the image aspect). Its three files: this module, orthographic.glsl beside
it, and the test. Nothing under rayvr/ names it."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rayvr.frame.cameras import CameraModel


@dataclass(frozen=True)
class Orthographic(CameraModel):
    name = "orthographic"
    glsl = str(Path(__file__).resolve().with_name("orthographic.glsl"))  # absolute: outside rayvr/glsl/
    converges = False  # parallel rays: no frustum to shear
    doc = "parallel rays from an image plane `height` tall (a test plugin)"
    height: float = 2.0  # the image plane's vertical extent, world units

    def __post_init__(self):
        if not float(self.height) > 0:
            raise ValueError(f"orthographic camera: height must be positive, got {self.height}")

    def check_rig(self, rig) -> None:
        if rig.eye_tangents:
            raise ValueError("orthographic camera: the image extent comes from height, not eye_tangents")

    def ray_at(self, eye, channel, x, y, lens):
        w, h = eye.size
        sx = (np.asarray(x) / w - 0.5) * self.height * w / h
        sy = (np.asarray(y) / h - 0.5) * self.height
        right, up, back = eye.rotation.T  # camera-to-world columns
        origins = eye.position + sx[..., None] * right + sy[..., None] * up
        directions = np.broadcast_to(-back, origins.shape).copy()
        return origins, directions, np.ones(sx.shape, bool)

    def uniforms(self, eyes, origin) -> dict:
        return {**super().uniforms(eyes, origin), "camera_height": np.float32(self.height)}
