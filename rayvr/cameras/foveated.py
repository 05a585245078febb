"""Foveated sampling: sample density falls off with eccentricity from a gaze point, following a
linear minimum-angle-of-resolution model (the acuity HVVR's foveated patterns and Guenter et al.
2012 use): the smallest angle the eye resolves at eccentricity e (degrees) is
    MAR(e) = fovea_mar + mar_slope * max(0, e - fovea_radius)
(`fovea_radius` is a flat zone for eye-tracking error), so the samples a pixel needs are
    density = clamp((pixel angle / MAR)^2, 1/4096, 1)
(the pixel angle: the square root of its solid angle, degrees). Samples lie on the eye's planar
frustum (the pinhole's rays); pixel p is a sample when its 64x64 ordered-dither (Bayer) rank,
(rank + 0.5) / 4096, is below the density there, so counts follow the density's integral and the
stride-2^k lattices are nested (the sparsest, every 64th pixel each way, is always sampled); the
last column and the top row are samples too, so every pixel lies in a cell with sampled corners.
A sample's footprint is 1 / sqrt(density) pixels (its sub-rays spread over it). The frame fills
the pixels between samples for display (`reconstruct`; GLSL in glsl/shade/samples_finish.comp):
bilinear between the corners of the finest lattice cell around the pixel (cut at the image's last
column / top row) whose four corners are samples. Depth and aux channels are left at the samples (0 between them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..limits import check_range
from .base import CameraModel
from .pinhole import Pinhole, planar_directions

DITHER_BITS = 6  # 64x64 ordered-dither tile: densities down to 1/4096
DITHER_LEVELS = 4 ** DITHER_BITS
BAYER_2X2 = np.array([[0, 2], [3, 1]])  # [y bit][x bit]
# Ranges of the acuity parameters (degrees): the density's (pixel angle / MAR)^2 stays far inside
# float32 for pixels up to 180 degrees, and no display has pixels near 1e-6 degrees.
MIN_MAR, MAX_ACUITY_DEGREES = 1e-6, 1e6


def dither_rank(x, y) -> np.ndarray:
    """Ordered-dither rank in [0, 4096) of GL pixel indices (x, y): the finest bits weigh most,
    so ranks below 4096 / 4^k are exactly the stride-2^k lattice."""
    x, y = np.asarray(x, np.int64), np.asarray(y, np.int64)
    rank = np.zeros(np.broadcast(x, y).shape, np.int64)
    for i in range(DITHER_BITS):
        rank += BAYER_2X2[(y >> i) & 1, (x >> i) & 1] * 4 ** (DITHER_BITS - 1 - i)
    return rank


@dataclass(frozen=True)
class Foveated(Pinhole):
    name = "foveated"
    rasterizable = False
    sparse = True
    glsl = "cameras/foveated.glsl"
    doc = "foveated samples: density falls off with eccentricity from the gaze (linear MAR), reconstructed"
    gaze: tuple = (0.5, 0.5)  # gaze point, fraction of the image (x right, y down), both eyes
    fovea_mar: float = 1.0 / 60.0  # degrees: MAR at the fovea (20/20 acuity)
    mar_slope: float = 0.022  # degrees of MAR per degree of eccentricity
    fovea_radius: float = 5.0  # degrees of full density around the gaze (eye-tracking error)

    rays = CameraModel.rays  # the generic path: footprints and the sample mask

    def __post_init__(self):
        g = tuple(float(v) for v in self.gaze)
        if len(g) != 2 or not all(0.0 <= v <= 1.0 for v in g):
            raise ValueError(f"foveated camera: gaze must be 2 fractions of the image in [0, 1], got {self.gaze!r}")
        object.__setattr__(self, "gaze", g)
        for key in ("fovea_mar", "mar_slope", "fovea_radius"):  # degrees; squared ratios stay within float32
            object.__setattr__(self, key, check_range(f"foveated camera: {key}", getattr(self, key),
                                                      MIN_MAR if key == "fovea_mar" else 0.0, MAX_ACUITY_DEGREES))

    def density(self, eye) -> np.ndarray:
        """(H, W) rows top-down: samples per pixel the model asks for at each pixel centre."""
        w, h = eye.size
        return self.density_at(eye, (np.arange(w) + 0.5)[None, :], (h - np.arange(h) - 0.5)[:, None])

    def density_at(self, eye, x, y) -> np.ndarray:
        """Samples per pixel (module notes) at GL image positions (x, y)."""
        w, h = eye.size
        l, r, b, t = eye.tangents
        d = planar_directions(eye, x, y)
        g = planar_directions(eye, self.gaze[0] * w, (1.0 - self.gaze[1]) * h)
        ecc = np.degrees(np.arctan2(np.linalg.norm(np.cross(d, g), axis=-1), d @ g))
        tx, ty = l + x / w * (r - l), b + y / h * (t - b)
        step = math.sqrt((r - l) / w * (t - b) / h)
        pixel = np.degrees(step / (1.0 + tx * tx + ty * ty) ** 0.75)
        mar = self.fovea_mar + self.mar_slope * np.maximum(ecc - self.fovea_radius, 0.0)
        return np.clip((pixel / mar) ** 2, 1.0 / DITHER_LEVELS, 1.0)

    def footprint(self, eye, channel: int = 0) -> np.ndarray:
        w, h = eye.size
        rho = self.density(eye)
        x, y = np.arange(w)[None, :], (h - 1 - np.arange(h))[:, None]  # GL rows
        sample = ((dither_rank(x, y) + 0.5) / DITHER_LEVELS < rho) | (x == w - 1) | (y == h - 1)
        return np.where(sample, 1.0 / np.sqrt(rho), 0.0)

    def reconstruct(self, eye, image: np.ndarray) -> np.ndarray:
        """Fill the pixels between samples of `image` ((H, W, C) rows top-down; values at the
        samples) as the GPU does: bilinear over the finest fully sampled lattice cell."""
        w, h = eye.size
        sample = self.footprint(eye)[::-1] > 0  # GL rows
        img = np.asarray(image, np.float64)[::-1]
        out = img.copy()
        for y in range(h):
            for x in range(w):
                if sample[y, x]:
                    continue
                for k in range(1, DITHER_BITS + 1):
                    s = 1 << k
                    x0, y0 = x // s * s, y // s * s
                    x1, y1 = min(x0 + s, w - 1), min(y0 + s, h - 1)
                    if sample[y0, x0] and sample[y0, x1] and sample[y1, x0] and sample[y1, x1]:
                        ax = (x - x0) / (x1 - x0) if x1 != x0 else 0.0
                        ay = (y - y0) / (y1 - y0) if y1 != y0 else 0.0
                        out[y, x] = ((1 - ax) * (1 - ay) * img[y0, x0] + ax * (1 - ay) * img[y0, x1] +
                                     (1 - ax) * ay * img[y1, x0] + ax * ay * img[y1, x1])
                        break
        return out[::-1]

    def uniforms(self, eyes, origin) -> dict:
        out = super().uniforms(eyes, origin)
        out["camera_gaze"] = np.array([self.gaze[0], 1.0 - self.gaze[1]], np.float32)  # GL: y up
        out["camera_mar"] = np.array([self.fovea_mar, self.mar_slope, self.fovea_radius], np.float32)
        return out
