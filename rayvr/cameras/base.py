"""The camera-model contract: a model turns an eye (rayvr.camera.EyeView) into rays, once as a
numpy reference (`rays`) and once in GLSL (the file named by `glsl`), and the two must agree.

Conventions shared by every model:
- numpy arrays are image rows top-down, as EyeView.ray_directions and the frames returned to
  users; pixel (x, y) has its centre at (x + 0.5, y + 0.5).
- GLSL works in GL image coordinates: x right, y *up* (row 0 is the bottom row), centres at +0.5.
- numpy origins are world positions (float64); GLSL origins are scene-local (world minus the
  scene origin, which is what `uniforms(eyes, origin)` subtracts), as every G-buffer position is.

The GLSL contract (a model's file is included by glsl/common/camera.glsl, which declares the
per-eye uniforms below; the model may declare more, named camera_*):

    // false: this sample makes no ray (e.g. outside a fisheye's image circle)
    bool camera_ray(int eye, vec2 pixel, vec2 size, out vec3 origin, out vec3 direction);
    // directions of the auxiliary rays one pixel right (+x) and one pixel up (+y, GL) of
    // `pixel`, from the same origin (Mitsuba's d_x / d_y): the texture-LOD footprint
    void camera_ray_neighbours(int eye, vec2 pixel, vec2 size, out vec3 direction_x, out vec3 direction_y);

Room for sampled models (HVVR's camera-as-samples, not built yet):
- `samples_per_pixel` S: a lens-distorted or foveated model lists S sample positions per pixel
  (HVVR: position in the pixel plus an ellipse footprint). Its `rays` would return arrays of
  shape (H, W, S, 3) (valid (H, W, S)); with S == 1 the sample axis is dropped, as here.
- `channels` C: per-colour-channel sample sets for chromatic correction (HVVR puts sample n in
  channel n mod C; C = 3 is RGB). `rays(eye, channel=c)` returns channel c's set; on the GPU the
  primary rays are cast once per channel set and the resolve takes channel c's colour from set c.
  The sample lists would live in an SSBO the model fills, with its GLSL `camera_ray` reading the
  sample for (pixel, sample, channel) instead of mapping the pixel centre.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

if TYPE_CHECKING:  # rayvr.camera imports this package; the eye is only a type here
    from ..camera import EyeView, StereoRig


@dataclass(frozen=True)
class CameraRays:
    """One eye's camera rays, rows top-down, world space (see the module notes).

    origins     (H, W, 3) float64 world positions
    directions  (H, W, 3) unit directions
    ddx, ddy    (H, W, 3) footprints: the derivative of the unit direction per pixel along +x
                (one column right) and along +y of the array (one row *down*); GL's "up"
                neighbour is therefore direction - ddy. Both are orthogonal to the direction.
    valid       (H, W) bool: False where the sample makes no ray (its other values are then
                meaningless)
    """

    origins: np.ndarray
    directions: np.ndarray
    ddx: np.ndarray
    ddy: np.ndarray
    valid: np.ndarray


class CameraModel:
    """Base of every camera model. Instances are immutable values (models are frozen
    dataclasses), one per rig; per-eye parameters (an HMD's lens per eye) are keyed by
    EyeView.name inside the model."""

    name: ClassVar[str]
    rasterizable: ClassVar[bool] = False  # only a planar pinhole can be rasterized
    glsl: ClassVar[str]  # the model's GLSL file, relative to rayvr/glsl/
    samples_per_pixel: ClassVar[int] = 1  # see the module notes
    channels: ClassVar[int] = 1

    @property
    def glsl_define(self) -> str:
        """The value of the CAMERA_MODEL define that selects this model in common/camera.glsl."""
        return "CAMERA_" + self.name.upper()

    def defines(self) -> dict:
        """Shader defines for programs that include common/camera.glsl."""
        return {"CAMERA_MODEL": self.glsl_define}

    def check_rig(self, rig: "StereoRig") -> None:
        """Refuse rig settings this model cannot render (ValueError); nothing by default."""

    def rays(self, eye: "EyeView", channel: int = 0) -> CameraRays:
        raise NotImplementedError

    def _check_channel(self, channel: int) -> None:
        if not 0 <= channel < self.channels:
            raise ValueError(f"camera model {self.name!r} has {self.channels} channel set(s), got channel {channel}")

    def uniforms(self, eyes: list["EyeView"], origin) -> dict:
        """Values of the per-eye uniforms of glsl/common/camera.glsl (float32 numpy arrays,
        GLSL layout), for up to two eyes (index = layer). A model with its own uniforms adds
        them to this dict. Both eyes share one model (their shaders are built for one)."""
        others = {e.camera.name for e in eyes} - {self.name}
        if others:
            raise ValueError(f"the eyes of one frame must share a camera model: {self.name!r} and {sorted(others)}")
        origin = np.asarray(origin, dtype=np.float64)
        position = np.zeros((2, 3), np.float32)
        rotation = np.zeros((2, 3, 3), np.float32)
        tangents = np.zeros((2, 4), np.float32)
        for i, eye in enumerate(eyes):
            position[i] = eye.position - origin  # float64 subtraction first: far-off rigs stay exact
            rotation[i] = eye.rotation.T  # GLSL mat3 is column-major
            tangents[i] = eye.tangents
        return {"eye_position": position, "eye_rotation": rotation, "eye_tangents": tangents,
                "eye_depth": np.array([eyes[0].near, eyes[0].far or 0.0], np.float32)}
