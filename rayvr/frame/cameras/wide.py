"""Wide field of view, to 210 x 130 degrees and beyond 180 (HVVR's spherical section): a
non-planar mapping in which equal pixel steps are equal angles.

- `spherical`: x is yaw, y is pitch (an equirectangular section): fov_y at most 180, fov_x 360.
- `equidistant` (fisheye): the angle from the view axis grows linearly with the distance from
  the image centre, in any direction (r = f theta); directions past 180 degrees make no ray.
The vertical field is the rig's fov_y; the horizontal one `fov_x`, or fov_y x width / height
(square pixels in angle). Convergence (a shear of planar frusta) does not apply. Depth (frames, G-buffer) is the distance along the ray, and near and far
are spheres: view depth means nothing sideways and behind. GLSL: glsl/cameras/wide.glsl.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...gl.limits import to_float32
from .base import CameraModel
from .pinhole import MIN_PIXEL_TANGENT

MAPPINGS = ("spherical", "equidistant")


@dataclass(frozen=True)
class Wide(CameraModel):
    name = "wide"
    glsl = "cameras/wide.glsl"
    wide_angle = True
    converges = False  # angles, not planar frusta: nothing to shear
    depth_along_ray = True
    doc = "wide field of view past 180 degrees: spherical section or equidistant fisheye"
    param_syntax = {"mapping": "|".join(MAPPINGS), "fov_x": "DEG"}
    mapping: str = "spherical"  # spherical | equidistant
    fov_x: float | None = None  # horizontal degrees (None: fov_y x width / height)

    def __post_init__(self):
        if self.mapping not in MAPPINGS:
            raise ValueError(f"wide camera: unknown mapping {self.mapping!r}; allowed: {', '.join(MAPPINGS)}")
        if self.fov_x is not None and not (0 < float(self.fov_x) <= 360):
            raise ValueError(f"wide camera: fov_x must be in (0, 360] degrees, got {self.fov_x}")

    def field(self, eye) -> tuple[float, float]:
        """(horizontal, vertical) field of view of `eye` in radians."""
        w, h = eye.size
        fy = math.radians(eye.fov_y)
        return (math.radians(self.fov_x) if self.fov_x is not None else fy * w / h), fy

    def transforms_fields(self, eye) -> dict:
        w, h = eye.size
        fx, fy = self.field(eye)
        if self.mapping == "spherical":  # yaw a = (x / w - 1/2) fov_x is pi (x - cx) / fl_x
            return {"camera_model": "EQUIRECTANGULAR", "fl_x": math.pi * w / fx, "fl_y": math.pi * h / fy,
                    "cx": w / 2, "cy": h / 2}
        # equidistant: the angle from the axis is |(a, b)|, a = (x - cx) / fl_x radians
        fields = {"camera_model": "OPENCV_FISHEYE", "fl_x": w / fx, "fl_y": h / fy, "cx": w / 2, "cy": h / 2,
                  "k1": 0.0, "k2": 0.0, "k3": 0.0, "k4": 0.0}
        if math.hypot(fx, fy) / 2 > math.pi:  # the corners lie past 180 degrees, where rayvr makes no ray:
            # nerfstudio then samples pixels within this radius of the centre only (a pixel inside, for its rounding)
            fields["fisheye_crop_radius"] = math.pi * min(fields["fl_x"], fields["fl_y"]) - 1.0
        return fields

    def check_rig(self, rig) -> None:
        if rig.eye_tangents:
            raise ValueError("wide camera: the field of view comes from fov_y (and fov_x), not eye_tangents")
        for eye in rig.eyes():
            fx, fy = (math.degrees(a) for a in self.field(eye))
            if self.mapping == "spherical" and fy > 180:
                raise ValueError(f"wide camera: the spherical mapping spans at most 180 degrees of pitch, got fov_y "
                                 f"{fy:g}; use the equidistant mapping")
            if fx > 360 or fy > 360:
                raise ValueError(f"wide camera: the field of view is at most 360 degrees, got {fx:g} x {fy:g} "
                                 f"(fov_x follows the image aspect unless given)")
            step = min(math.radians(fx) / eye.size[0], math.radians(fy) / eye.size[1])
            if step < MIN_PIXEL_TANGENT:  # the planar models' float32 limit, as an angle
                raise ValueError(f"wide camera: a {fx:g} x {fy:g} degree field on a {eye.size[0]}x{eye.size[1]} "
                                 f"image makes pixels of {step:.3g} radians; float32 rays resolve pixels down to "
                                 f"{MIN_PIXEL_TANGENT:.0e} radians")

    def ray_at(self, eye, channel, x, y, lens):
        w, h = eye.size
        fx, fy = self.field(eye)
        a = (np.asarray(x, np.float64) / w - 0.5) * fx
        b = (np.asarray(y, np.float64) / h - 0.5) * fy
        a, b = np.broadcast_arrays(a, b)
        if self.mapping == "spherical":
            v = np.stack([np.sin(a) * np.cos(b), np.sin(b), -np.cos(a) * np.cos(b)], axis=-1)
            valid = np.ones(a.shape, bool)
        else:
            theta = np.hypot(a, b)
            sinc = np.where(theta > 1e-8, np.sin(theta) / np.where(theta > 1e-8, theta, 1.0), 1.0)
            v = np.stack([sinc * a, sinc * b, -np.cos(theta)], axis=-1)
            valid = theta <= math.pi
        return np.asarray(eye.position, np.float64), v @ eye.rotation.T, valid

    def solid_angle(self, eye) -> float:
        """The solid angle (steradians) the eye's image covers, analytically (spherical) or by a
        fine midpoint rule over the image's angles (equidistant)."""
        fx, fy = self.field(eye)
        if self.mapping == "spherical":
            return fx * 2.0 * math.sin(fy / 2.0)
        n = 1500
        a = (np.arange(n) + 0.5) / n * fx - fx / 2
        b = (np.arange(n) + 0.5) / n * fy - fy / 2
        theta = np.hypot(a[None, :], b[:, None])
        jac = np.where(theta <= math.pi, np.sinc(theta / math.pi), 0.0)  # sin(theta) / theta
        return float(jac.sum() * (fx / n) * (fy / n))

    def uniforms(self, eyes, origin) -> dict:
        out = super().uniforms(eyes, origin)
        out["camera_fov"] = to_float32("wide camera: field of view", self.field(eyes[0]))
        out["camera_mapping"] = np.array([MAPPINGS.index(self.mapping)], np.int32)
        return out
