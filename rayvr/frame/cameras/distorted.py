"""HMD lens pre-distortion: every display pixel is sampled where the headset's lens will show it,
so the image needs no distortion pass afterwards (HVVR's pre-distorted rendering), and each
colour channel has its own sample grid: the lens bends red, green and blue differently
(chromatic aberration), and sampling each on its own rays pre-corrects that.

Parametric model: a panel point q (tangent units on the eye's planar frustum: the pinhole's
mapping of the pixel) is seen through the lens at view tangent
    u = c + (q - c) * (1 + k1 r^2 + k2 r^4 + k3 r^6),   r = |q - c|,
with one (k1, k2, k3) per channel and the lens centre c (given for the left eye, mirrored in x
for the right one). `distort` is this map, `undistort` its numerical inverse (safeguarded Newton
on the radius); the map must be monotonic over the panel (checked per rig), else it folds and has
no inverse.

Or measured: a sample file (`samples=`), one sample per line
    x y channel dx dy dz
with the pixel (column, row; rows top-down), the channel (0 1 2 or r g b; a file of channel 0
alone is one set for all three) and the eye-space direction (x right, y up, -z forward) the lens
shows that subpixel at. Pixels without a line make no ray; sub-rays between sample centres
interpolate the neighbours' directions bilinearly. GLSL: glsl/cameras/distorted.glsl.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...util.inputs import MAX_IMAGE_SIDE, read_text
from ...gl.limits import check_range, to_float32
from .base import CameraModel, normalize, planar_transforms_fields
from .pinhole import MAX_TANGENT, check_planar_rig

# Per channel R, G, B: a pincushion lens of a consumer HMD class, blue bent most.
DEFAULT_COEFFICIENTS = ((0.21, 0.22, 0.0), (0.22, 0.24, 0.0), (0.235, 0.265, 0.0))
CHANNEL_NAMES = "rgb"
# A sample file is read whole: three channels of a 2k x 2k panel at full precision (write_samples) fit.
MAX_SAMPLE_FILE_BYTES = 2 << 30


def _coefficients(value) -> tuple:
    """((k1, k2, k3),) * 3 from one triple or three (shorter polynomials are padded with 0)."""
    try:
        arr = [list(map(float, value))] if all(isinstance(v, (int, float)) for v in value) else \
            [list(map(float, v)) for v in value]
    except (TypeError, ValueError):
        raise ValueError(f"distorted camera: coefficients must be (k1, k2, k3) or one such triple per channel "
                         f"R, G, B, got {value!r}") from None
    if len(arr) not in (1, 3) or not all(1 <= len(k) <= 3 for k in arr):
        raise ValueError(f"distorted camera: coefficients must be 1 to 3 numbers, for all channels or for each of "
                         f"R, G, B, got {value!r}")
    if not all(math.isfinite(x) for k in arr for x in k):
        raise ValueError(f"distorted camera: coefficients must be finite, got {value!r}")
    arr = [tuple(k + [0.0] * (3 - len(k))) for k in arr]
    return tuple(arr * 3) if len(arr) == 1 else tuple(arr)


@dataclass(frozen=True)
class SampleTable:
    """A sample file's directions: (C, H, W, 3) eye-space unit vectors and (C, H, W) validity,
    rows bottom-up (GL order, as the GPU texture)."""

    path: str
    directions: np.ndarray
    valid: np.ndarray

    @property
    def size(self) -> tuple:
        return self.valid.shape[2], self.valid.shape[1]

    @property
    def channels(self) -> int:
        return self.valid.shape[0]


def load_samples(path) -> SampleTable:
    """Read and validate a sample file (module notes); errors name the file and line."""
    path = Path(path)
    text = read_text(path, "camera sample file", MAX_SAMPLE_FILE_BYTES)
    rows, first = [], {}
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != 6:
            raise ValueError(f"{path}:{lineno}: expected 6 values 'x y channel dx dy dz', got {len(parts)}")
        try:
            x, y = int(parts[0]), int(parts[1])
        except ValueError:
            raise ValueError(f"{path}:{lineno}: pixel must be two integers (column row), got {parts[0]} {parts[1]}") from None
        c = parts[2].lower()
        c = CHANNEL_NAMES.index(c) if c in CHANNEL_NAMES else (int(c) if c in ("0", "1", "2") else None)
        if c is None:
            raise ValueError(f"{path}:{lineno}: channel must be 0, 1, 2 or r, g, b, got {parts[2]!r}")
        try:
            d = [float(v) for v in parts[3:]]
        except ValueError:
            raise ValueError(f"{path}:{lineno}: direction must be 3 numbers, got {' '.join(parts[3:])}") from None
        if x < 0 or y < 0:
            raise ValueError(f"{path}:{lineno}: pixel ({x}, {y}) is negative")
        if x >= MAX_IMAGE_SIDE or y >= MAX_IMAGE_SIDE:  # the table is dense, as large as its last pixel
            raise ValueError(f"{path}:{lineno}: pixel ({x}, {y}) lies outside the largest image rayvr renders, "
                             f"{MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE}")
        if not all(math.isfinite(v) for v in d) or not any(d):
            raise ValueError(f"{path}:{lineno}: direction ({', '.join(parts[3:])}) must be finite and non-zero")
        if (x, y, c) in first:
            raise ValueError(f"{path}:{lineno}: pixel ({x}, {y}) channel {c} again (first on line {first[x, y, c]})")
        first[x, y, c] = lineno
        rows.append((x, y, c, *d))
    if not rows:
        raise ValueError(f"{path}: the camera sample file has no samples")
    a = np.array(rows)
    xs, ys, cs = (a[:, i].astype(int) for i in range(3))
    channels = int(cs.max()) + 1
    if channels == 2 or (channels == 3 and set(cs) != {0, 1, 2}):
        raise ValueError(f"{path}: samples for channels {sorted(set(cs.tolist()))}: give channel 0 alone (one set for "
                         f"all) or all of 0, 1, 2")
    w, h = int(xs.max()) + 1, int(ys.max()) + 1
    dirs = np.zeros((channels, h, w, 3))
    valid = np.zeros((channels, h, w), bool)
    rows_gl = h - 1 - ys
    dirs[cs, rows_gl, xs] = normalize(a[:, 3:])
    valid[cs, rows_gl, xs] = True
    return SampleTable(str(path), dirs, valid)


def write_samples(path, directions, valid=None) -> None:
    """Write a sample file from (C, H, W, 3) eye-space directions, rows top-down (for tools and
    tests: e.g. a parametric model's rays, to load back as a measured table)."""
    directions = np.asarray(directions, np.float64)
    c, h, w, _ = directions.shape
    valid = np.ones((c, h, w), bool) if valid is None else valid
    lines = ["# x y channel dx dy dz (rayvr camera sample file)"]
    for ch in range(c):
        for y in range(h):
            for x in range(w):
                if valid[ch, y, x]:
                    d = directions[ch, y, x]
                    lines.append(f"{x} {y} {ch} {d[0]:.17g} {d[1]:.17g} {d[2]:.17g}")
    Path(path).write_text("\n".join(lines) + "\n")


@dataclass(frozen=True)
class Distorted(CameraModel):
    name = "distorted"
    glsl = "cameras/distorted.glsl"
    doc = "HMD lens pre-distortion: radial polynomial per colour channel (or a sample file)"
    param_syntax = {"coefficients": "K1,K2,K3[/K1,K2,K3/K1,K2,K3]", "center": "CX,CY", "samples": "FILE"}
    coefficients: tuple = DEFAULT_COEFFICIENTS  # (k1, k2, k3) per channel R, G, B, or one triple for all
    center: tuple = (0.0, 0.0)  # lens centre on the left eye's panel (tangent units); mirrored for the right
    samples: str | None = None  # a measured sample file instead of the polynomial

    def __post_init__(self):
        object.__setattr__(self, "coefficients", _coefficients(self.coefficients))
        c = tuple(float(v) for v in self.center)
        if len(c) != 2 or not all(math.isfinite(v) for v in c):
            raise ValueError(f"distorted camera: center must be 2 finite numbers, got {self.center!r}")
        for axis, v in zip("xy", c):  # tangent units, as the panel's: the same float32 precision limit
            check_range(f"distorted camera: center {axis}", v, -MAX_TANGENT, MAX_TANGENT)
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "_table", load_samples(self.samples) if self.samples else None)
        object.__setattr__(self, "_textures", {})

    @property
    def channels(self) -> int:
        if self._table is not None:
            return self._table.channels
        return 1 if len(set(self.coefficients)) == 1 else 3

    def lens_center(self, eye) -> np.ndarray:
        return np.array([-self.center[0] if eye.name == "right" else self.center[0], self.center[1]])

    # -- the parametric map and its inverse ----------------------------------------
    def _k(self, channel: int) -> tuple:
        return self.coefficients[channel if self.channels > 1 else 0]

    def distort(self, q, channel: int = 0, center=(0.0, 0.0)) -> np.ndarray:
        """Panel tangents q (..., 2) -> the view tangents the lens shows them at."""
        k1, k2, k3 = self._k(channel)
        rel = np.asarray(q, np.float64) - center
        r2 = np.sum(rel * rel, axis=-1, keepdims=True)
        return center + rel * (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))

    def undistort(self, u, channel: int = 0, center=(0.0, 0.0), max_radius: float | None = None) -> np.ndarray:
        """The inverse of `distort`: view tangents u (..., 2) -> panel tangents. Newton on the
        radius, kept inside a bisection bracket [0, max_radius] (default: where the image of the
        radius first exceeds |u - c|)."""
        k1, k2, k3 = self._k(channel)
        rel = np.asarray(u, np.float64) - center
        rho = np.linalg.norm(rel, axis=-1)
        g = lambda s: s * (1.0 + s * s * (k1 + s * s * (k2 + s * s * k3)))  # noqa: E731
        dg = lambda s: 1.0 + s * s * (3 * k1 + s * s * (5 * k2 + s * s * 7 * k3))  # noqa: E731
        lo = np.zeros_like(rho)
        hi = np.full_like(rho, max_radius) if max_radius is not None else np.maximum(rho, 1e-300)
        if max_radius is None:  # grow the bracket until it holds the root
            for _ in range(200):
                short = g(hi) < rho
                if not short.any():
                    break
                hi = np.where(short, hi * 2.0, hi)
        s = np.clip(rho, lo, hi)
        for _ in range(100):
            f = g(s) - rho
            lo = np.where(f < 0, s, lo)
            hi = np.where(f > 0, s, hi)
            step = s - f / np.where(dg(s) != 0, dg(s), 1.0)
            inside = (step > lo) & (step < hi)
            new = np.where(inside, step, 0.5 * (lo + hi))
            if np.array_equal(new, s):
                break
            s = new
        scale = np.where(rho > 0, s / np.where(rho > 0, rho, 1.0), 1.0)
        return center + rel * scale[..., None]

    def transforms_fields(self, eye) -> dict:
        if self.samples:
            raise self.not_described(f"its rays come from the measured sample file {self.samples}")
        if any(any(k) for k in self.coefficients):
            raise self.not_described("its polynomial maps image points to view tangents, the inverse of OpenCV's "
                                     "radial model, around its own lens centre and per colour channel; use "
                                     "coefficients=0 (a pinhole) or the pinhole")
        return planar_transforms_fields(eye)  # no distortion: the pinhole's panel

    def check_rig(self, rig) -> None:
        if self._table is not None:
            if tuple(rig.size) != self._table.size:
                w, h = self._table.size
                raise ValueError(f"{self._table.path}: the sample file covers {w}x{h} pixels, the eye image is "
                                 f"{rig.size[0]}x{rig.size[1]}: render at {w}x{h}")
            return
        for eye in rig.eyes():
            l, r, b, t = eye.tangents
            if not all(math.isfinite(v) for v in eye.tangents) or not (r > l and t > b):
                raise ValueError(f"distorted camera: the {eye.name} eye's panel needs finite frustum tangents "
                                 f"(fov_y < 180), got {eye.tangents}")
        check_planar_rig(rig)  # the panel is the pinhole's frustum, with its float32 limits
        for eye in rig.eyes():
            l, r, b, t = eye.tangents
            c = self.lens_center(eye)
            reach = max(math.hypot(x - c[0], y - c[1]) for x in (l, r) for y in (b, t))
            for ch in range(self.channels):
                self._check_polynomial(ch, reach, eye.name)

    def _check_polynomial(self, channel: int, reach: float, eye: str) -> None:
        """Refuse a channel's polynomial that folds over radii [0, reach] (no inverse) or whose
        view tangents leave float32's planar precision there. Exact, and safe from overflow: the
        size of every term is bounded before the slope is looked at."""
        k = self._k(channel)
        name = CHANNEL_NAMES[channel].upper() if self.channels > 1 else "every channel"
        # |u - c| <= r (1 + |k1| r^2 + |k2| r^4 + |k3| r^6): a bound on the view tangent offset, in
        # plain float64 products (an enormous coefficient gives inf, which is refused too).
        r2 = reach * reach
        bound = reach * (1.0 + abs(k[0]) * r2 + abs(k[1]) * r2 * r2 + abs(k[2]) * r2 * r2 * r2)
        if not bound <= MAX_TANGENT:
            raise ValueError(f"distorted camera: the lens polynomial of {name} {k} can reach view tangent "
                             f"{bound:.3g} at the {eye} eye's panel radius {reach:.4g}; rays end at tangent "
                             f"{MAX_TANGENT:.0e} (float32 planar precision): use smaller coefficients")
        # The map's radial slope, a cubic in x = r^2: 1 + 3 k1 x + 5 k2 x^2 + 7 k3 x^3. It folds where
        # the slope reaches 0; its minimum over [0, reach^2] lies at an end or where its derivative
        # 3 k1 + 10 k2 x + 21 k3 x^2 vanishes.
        slope = lambda x: 1.0 + x * (3 * k[0] + x * (5 * k[1] + x * 7 * k[2]))  # noqa: E731
        stationary = np.roots([21 * k[2], 10 * k[1], 3 * k[0]]) if any(k) else np.array([])
        candidates = [r2] + [float(x.real) for x in np.atleast_1d(stationary)
                             if abs(x.imag) <= 1e-12 * max(1.0, abs(x)) and 0.0 < x.real < r2]
        low = min(candidates, key=slope)
        if slope(low) > 0:
            return
        lo, hi = 0.0, low  # slope(0) = 1 > 0 >= slope(low): bisect for where it first folds
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if slope(mid) > 0 else (lo, mid)
        raise ValueError(f"distorted camera: the lens polynomial of {name} {k} folds over at radius "
                         f"{math.sqrt(hi):.4g} of the {eye} eye's panel, which reaches {reach:.4g}: it has no "
                         f"inverse there (use smaller coefficients)")

    # -- rays -----------------------------------------------------------------------
    def ray_at(self, eye, channel, x, y, lens):
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        if self._table is not None:
            v, valid = self._table_at(channel, x, y)
            v = np.where(valid[..., None], v, (0.0, 0.0, -1.0))  # no sample near: the view axis (as the GLSL)
        else:
            w, h = eye.size
            l, r, b, t = eye.tangents
            q = np.stack(np.broadcast_arrays(l + x / w * (r - l), b + y / h * (t - b)), axis=-1)
            u = self.distort(q, channel, self.lens_center(eye))
            v = np.concatenate([u, -np.ones(u.shape[:-1] + (1,))], axis=-1)
            valid = np.ones(u.shape[:-1], bool)
        return np.asarray(eye.position, np.float64), normalize(v @ eye.rotation.T), valid

    def _table_at(self, channel, x, y):
        """Bilinear interpolation of the valid sample directions around GL positions (x, y)."""
        t = self._table
        w, h = t.size
        fx, fy = x - 0.5, y - 0.5
        x0, y0 = np.floor(fx), np.floor(fy)
        ax, ay = fx - x0, fy - y0
        v = np.zeros(x.shape + (3,))
        weight = np.zeros(x.shape)
        for dx, dy, wgt in ((0, 0, (1 - ax) * (1 - ay)), (1, 0, ax * (1 - ay)), (0, 1, (1 - ax) * ay), (1, 1, ax * ay)):
            i = np.clip(x0 + dx, 0, w - 1).astype(int)
            j = np.clip(y0 + dy, 0, h - 1).astype(int)
            ok = t.valid[channel, j, i]
            v += (wgt * ok)[..., None] * t.directions[channel, j, i]
            weight += wgt * ok
        return v, weight > 0

    def footprint(self, eye, channel: int = 0) -> np.ndarray:
        if self._table is None:
            return super().footprint(eye, channel)
        return self._table.valid[channel, ::-1].astype(np.float64)  # rows top-down

    # -- GPU ------------------------------------------------------------------------
    def uniforms(self, eyes, origin) -> dict:
        out = super().uniforms(eyes, origin)
        out["camera_lens_k"] = to_float32("distorted camera: coefficients", [self._k(c) for c in range(3)])
        out["camera_lens_center"] = to_float32("distorted camera: center", [self.lens_center(e) for e in eyes] +
                                               [(0.0, 0.0)] * (2 - len(eyes)))
        out["camera_use_table"] = np.array([int(self._table is not None)], np.int32)
        return out

    def bind(self, gl) -> None:
        from ...gl.gpu_layout import UNIT

        if self._table is None:
            return
        tex = self._textures.get(id(gl.ctx))
        if tex is None:
            t = self._table
            data = np.concatenate([t.directions, t.valid[..., None]], axis=-1).astype(np.float32)
            import moderngl

            tex = gl.ctx.texture_array((t.size[0], t.size[1], t.channels), 4, data.tobytes(), dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._textures[id(gl.ctx)] = tex
        tex.use(UNIT["camera_samples"])
