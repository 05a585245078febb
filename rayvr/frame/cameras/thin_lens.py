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

from ...gl.limits import MAX_CAMERA_COORDINATE, MAX_FOCUS_DISTANCE, MIN_DISTANCE, check_range, to_float32
from .base import CameraModel, normalize
from .pinhole import Pinhole, planar_directions


# float32 rounds a lens ray's origin and direction each to ~1.2e-7 of the lens radius, which moves
# where the ray meets the scene by ~2.4e-7 of the aperture; kept under a tenth of a pixel at the
# focus distance. Measured on the default room at 64x48, focus 2 (limit 3.5e4), 32 sub-rays: 30,
# 3e3 and 3e4 give the same blur (mean 24.4-24.6 of 255), 3e6 drifts (26.3), 1e12 is all background.
LENS_ROUNDING = 2.4e-7
LENS_PIXEL_FRACTION = 0.1


@dataclass(frozen=True)
class ThinLens(Pinhole):
    name = "dof"
    rasterizable = False
    # Lens rays widen the tiles' frusta: culled tiles were slower in the room at every focus,
    # but with block culling faster on Sponza's worst poses at every count (docs/design.md).
    culls_tiles_by_default = True
    lens_parameter = "aperture"
    judged_by_pinhole = False  # out of focus it blurs the pinhole's image on purpose
    glsl = "cameras/thin_lens.glsl"
    doc = "thin-lens depth of field (aperture radius, focus distance); lens positions per sub-ray"
    param_syntax = {"aperture": "RADIUS (the lens radius; --dof-diameter is the screen-space blur's lens diameter)",
                    "focus": "D"}
    aperture: float = 0.01  # lens radius, world units
    focus: float = 2.0  # focus distance along the view axis, world units

    rays = CameraModel.rays  # the generic path: lens points per sub-ray

    def __post_init__(self):
        # The lens offsets the rays' origins (so it spans no more than a camera may lie from the
        # scene); the shaders square the distance to the focal point (rayvr/gl/limits.py).
        object.__setattr__(self, "aperture", check_range("dof camera: aperture (lens radius)", self.aperture, 0.0,
                                                         MAX_CAMERA_COORDINATE))
        object.__setattr__(self, "focus", check_range("dof camera: focus distance", self.focus, MIN_DISTANCE,
                                                      MAX_FOCUS_DISTANCE))

    def check_rig(self, rig) -> None:
        super().check_rig(rig)  # the planar frustum's limits
        for eye in rig.eyes():
            l, r, b, t = eye.tangents
            pixel = self.focus * min((r - l) / eye.size[0], (t - b) / eye.size[1])  # a pixel at the focus distance
            widest = LENS_PIXEL_FRACTION * pixel / LENS_ROUNDING
            if self.aperture > widest:
                raise ValueError(f"dof camera: aperture {self.aperture:g} is wider than {widest:.3g}, where float32 "
                                 f"rounding of the lens rays moves them {LENS_PIXEL_FRACTION:g} of a pixel at focus "
                                 f"{self.focus:g} on the {eye.name} eye's {eye.size[0]}x{eye.size[1]} image")

    def transforms_fields(self, eye) -> dict:
        if self.aperture > 0:
            raise self.not_described(f"its images are blurred by a lens of radius {self.aperture:g}; use aperture=0 "
                                     "(a pinhole) or the pinhole")
        return super().transforms_fields(eye)  # a pinhole

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
