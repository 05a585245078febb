"""Thin-lens depth of field: a lens of radius `aperture` (world units) focused at `focus` (view
depth). Sub-ray i starts at lens point lens_i (sampling.py: the same set for every pixel and both
eyes, so the two eyes' blur agrees) and goes through the point the pinhole ray of its image
position meets at view depth `focus`. The central ray (lens centre) is the pinhole's; aperture 0
is the pinhole. Blur needs several sub-rays per sample (--msaa / --ssaa N).
GLSL: glsl/cameras/thin_lens.glsl.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..limits import MAX_CAMERA_COORDINATE, MAX_DISTANCE, MIN_DISTANCE, check_range, to_float32
from .base import CameraModel, normalize
from .pinhole import Pinhole, planar_directions


@dataclass(frozen=True)
class ThinLens(Pinhole):
    name = "dof"
    rasterizable = False
    glsl = "cameras/thin_lens.glsl"
    doc = "thin-lens depth of field (aperture radius, focus distance); lens positions per sub-ray"
    aperture: float = 0.01  # lens radius, world units
    focus: float = 2.0  # focus distance along the view axis, world units

    rays = CameraModel.rays  # the generic path: lens points per sub-ray

    def __post_init__(self):
        # The lens offsets the rays' origins (so it spans no more than a camera may lie from the
        # scene); a focus distance is squared in the shaders, so it has the near plane's range.
        object.__setattr__(self, "aperture", check_range("dof camera: aperture (lens radius)", self.aperture, 0.0,
                                                         MAX_CAMERA_COORDINATE))
        object.__setattr__(self, "focus", check_range("dof camera: focus distance", self.focus, MIN_DISTANCE,
                                                      MAX_DISTANCE))

    def ray_at(self, eye, channel, x, y, lens):
        d = planar_directions(eye, x, y)
        forward = -eye.rotation[:, 2]
        focal = d * (self.focus / (d @ forward))[..., None]  # from the eye centre
        offset = self.aperture * (lens[0] * eye.rotation[:, 0] + lens[1] * eye.rotation[:, 1])
        return np.asarray(eye.position, np.float64) + offset, normalize(focal - offset), np.ones(d.shape[:-1], bool)

    def uniforms(self, eyes, origin) -> dict:
        out = super().uniforms(eyes, origin)
        out["camera_thin_lens"] = to_float32("dof camera: aperture, focus", [self.aperture, self.focus])
        return out
