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
the pixels between samples for display (`reconstruct`; GLSL in glsl/cameras/foveated_resolve.glsl),
coarse to fine by diamond-square: on each level k = 5 .. 0, the centres of the stride-2^(k+1)
cells that are not samples are the mean of the linear fills between the cell's opposite edge
midpoints along x and along y, each its sample or else linear between the cell corners beside it
(cut at the image's last column / top row; bilinear when no midpoint is a sample), then the
cells' edge midpoints the mean of the linear fills between their
neighbours 2^k away along x and along y, each a sample or a point filled before (exact on an
image linear in the fill's units). So every sample
is a corner of the cells around it (a fill from the finest cell whose four corners were all
samples skipped the samples of a partial lattice inside it: single dots along edges). The fill
is made in display-like units, y = x / (1 + x) of the exposed colour x, and expanded back: in
linear HDR a light's samples outweigh the dark ones beside them, and the fill showed white around
each dark sample. Depth and aux channels are left at the samples (0 between them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...gl.glsl_constants import declare
from ...gl.limits import check_range
from .base import CameraModel
from .pinhole import Pinhole, planar_directions

DITHER_BITS = declare("DITHER_BITS", 6)  # 64x64 ordered-dither tile: densities down to 1/4096
DITHER_LEVELS = declare("DITHER_LEVELS", 4 ** DITHER_BITS)
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
    culls_tiles_by_default = False  # sparse samples: tile culling measured 5.9 -> 8.9 ms (docs/design.md)
    judged_by_pinhole = True  # a sparse sampling of the pinhole's image
    sparse = True
    glsl = "cameras/foveated.glsl"
    reconstruction = "cameras/foveated_resolve.glsl"
    doc = "foveated samples: density falls off with eccentricity from the gaze (linear MAR), reconstructed"
    param_syntax = {"gaze": "X,Y", "fovea_mar": "DEG", "mar_slope": "S", "fovea_radius": "DEG"}
    gaze: tuple = (0.5, 0.5)  # gaze point, fraction of the image (x right, y down), both eyes
    fovea_mar: float = 1.0 / 60.0  # degrees: MAR at the fovea (20/20 acuity)
    mar_slope: float = 0.022  # degrees of MAR per degree of eccentricity
    fovea_radius: float = 5.0  # degrees of full density around the gaze (eye-tracking error)

    rays = CameraModel.rays  # the generic path: footprints and the sample mask

    def transforms_fields(self, eye) -> dict:
        raise self.not_described("its images are filled in between samples that thin out away from the gaze, and "
                                 "depth exists only at the samples; use the pinhole")

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

    def resolve_steps(self) -> list[dict]:
        """Copy the samples, then fill coarse to fine: on each level the cell centres, then the edges."""
        return [{"resolve_level": DITHER_BITS, "resolve_step": 0}] + [
            {"resolve_level": k, "resolve_step": step} for k in range(DITHER_BITS - 1, -1, -1) for step in (0, 1)]

    def reconstruct(self, eye, image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
        """Fill the pixels between samples of `image` ((H, W, C) linear colour, rows top-down;
        values at the samples) as the GPU does (module notes): level by level, coarse to fine, the
        non-sample centres of the stride-2^(k+1) cells, then their edge midpoints (diamond-square),
        in the display-like units x / (1 + x) of the colour x times `exposure`."""
        w, h = eye.size
        sample = self.footprint(eye)[::-1] > 0  # GL rows
        img = np.asarray(image, np.float64)[::-1]
        exposed = np.maximum(img, 0.0) * exposure
        out = np.where(sample[..., None], exposed / (1.0 + exposed), 0.0)
        ys, xs = np.mgrid[0:h, 0:w]

        def between(y, x, s, axis, values=None):
            """Linear between the points s before and s after along `axis` (after: cut at the
            image); `values` (before, after) replace the points' own."""
            ya, xa = (y, x - s) if axis == 0 else (y - s, x)
            yb, xb = (y, np.minimum(x + s, w - 1)) if axis == 0 else (np.minimum(y + s, h - 1), x)
            ya, xa = np.maximum(ya, 0), np.maximum(xa, 0)  # (the first column / row: unused)
            va, vb = values if values is not None else (out[ya, xa], out[yb, xb])
            a = (s / ((xb - xa) + (yb - ya)))[:, None]
            return (1 - a) * va + a * vb

        def midpoint(y, x, s, axis):  # a centre's edge midpoint: its sample, else between its corners
            return np.where(sample[y, x][:, None], out[y, x], between(y, x, s, 1 - axis))

        for k in range(DITHER_BITS - 1, -1, -1):  # the stride-2^DITHER_BITS lattice is all samples
            s = 1 << k
            todo = (xs % s == 0) & (ys % s == 0) & ~sample
            ox, oy = (xs // s) & 1, (ys // s) & 1
            y, x = ys[todo & (ox == 1) & (oy == 1)], xs[todo & (ox == 1) & (oy == 1)]  # cell centres
            xr, yt = np.minimum(x + s, w - 1), np.minimum(y + s, h - 1)
            along_x = between(y, x, s, 0, (midpoint(y, x - s, s, 0), midpoint(y, xr, s, 0)))
            along_y = between(y, x, s, 1, (midpoint(y - s, x, s, 1), midpoint(yt, x, s, 1)))
            out[y, x] = 0.5 * (along_x + along_y)
            y, x = ys[todo & ((ox ^ oy) == 1)], xs[todo & ((ox ^ oy) == 1)]  # edge midpoints
            horizontal, vertical = between(y, x, s, 0), between(y, x, s, 1)
            # On the image's first column / row the neighbour before is outside: along its edge only.
            out[y, x] = np.where((x == 0)[:, None], vertical,
                                 np.where((y == 0)[:, None], horizontal, 0.5 * (horizontal + vertical)))
        filled = out / np.maximum(1.0 - out, 1e-7) / exposure
        return np.where(sample[..., None], img, filled)[::-1]

    def uniforms(self, eyes, origin) -> dict:
        out = super().uniforms(eyes, origin)
        out["camera_gaze"] = np.array([self.gaze[0], 1.0 - self.gaze[1]], np.float32)  # GL: y up
        out["camera_mar"] = np.array([self.fovea_mar, self.mar_slope, self.fovea_radius], np.float32)
        return out
