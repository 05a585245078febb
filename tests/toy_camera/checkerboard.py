"""A checkerboard camera, a sparse model from outside rayvr (tests/test_camera_plugin.py registers
it): the pinhole's rays at the pixels of one colour of a checkerboard, the others filled for
display with the mean of their neighbours left, right, below and above inside the image (all
samples), in the display-like units x / (1 + x) of the exposed colour x, as the foveated fill.
Its files: this module, checkerboard.glsl (the rays) and checkerboard_resolve.glsl (the fill)
beside it. Nothing under rayvr/ names it."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rayvr.frame.cameras import CameraModel, Pinhole

HERE = Path(__file__).resolve().parent
PARITIES = ("even", "odd")


@dataclass(frozen=True)
class Checkerboard(Pinhole):
    name = "checkerboard"
    rasterizable = False  # a rasterizer samples every pixel
    judged_by_pinhole = True  # its samples are the pinhole's pixels: the pinhole reference judges it
    sparse = True
    glsl = str(HERE / "checkerboard.glsl")  # absolute: outside rayvr/glsl/
    reconstruction = str(HERE / "checkerboard_resolve.glsl")
    doc = "the pinhole's rays at every other pixel, a checkerboard, the gaps averaged (a test plugin)"
    param_syntax = {"parity": "|".join(PARITIES)}
    parity: str = "even"  # the sampled squares: GL pixels (x, y up) whose x + y is even, or odd

    rays = CameraModel.rays  # the generic path, which reads the footprints: no ray between samples

    def __post_init__(self):
        if self.parity not in PARITIES:
            raise ValueError(f"checkerboard camera: parity must be one of {', '.join(PARITIES)}, got {self.parity!r}")

    def check_rig(self, rig) -> None:
        super().check_rig(rig)
        if min(rig.size) < 2:  # a gap must have a neighbour
            raise ValueError(f"checkerboard camera: the image must be 2x2 at least, got {rig.size[0]}x{rig.size[1]}")

    def footprint(self, eye, channel: int = 0) -> np.ndarray:
        w, h = eye.size
        x, y = np.arange(w)[None, :], (h - 1 - np.arange(h))[:, None]  # GL rows: y up
        return (((x + y) & 1) == PARITIES.index(self.parity)).astype(np.float64)

    def resolve_steps(self) -> list[dict]:
        return [{"resolve_step": 0}, {"resolve_step": 1}]  # samples into the fill, then the gaps

    def reconstruct(self, eye, image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
        """The numpy twin of checkerboard_resolve.glsl: samples as they are, each gap the mean of its
        neighbours inside the image, averaged in the units x / (1 + x) of the exposed colour x."""
        sample = self.footprint(eye) > 0
        img = np.asarray(image, np.float64)
        exposed = np.maximum(img, 0.0) * exposure
        units = np.pad(np.where(sample[..., None], exposed / (1.0 + exposed), 0.0), ((1, 1), (1, 1), (0, 0)))
        inside = np.pad(np.ones(sample.shape), 1)
        total = units[:-2, 1:-1] + units[2:, 1:-1] + units[1:-1, :-2] + units[1:-1, 2:]
        count = inside[:-2, 1:-1] + inside[2:, 1:-1] + inside[1:-1, :-2] + inside[1:-1, 2:]
        mean = total / count[..., None]
        return np.where(sample[..., None], img, mean / np.maximum(1.0 - mean, 1e-7) / exposure)

    def uniforms(self, eyes, origin) -> dict:
        return {**super().uniforms(eyes, origin), "camera_parity": np.int32(PARITIES.index(self.parity))}
