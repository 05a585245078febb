"""The denoiser in numpy: the slow reference of glsl/post/denoise.comp (rayvr/frame/passes/denoise.py),
written from the algorithm (SVGF's à-trous wavelet with edge-stops, Schied et al. 2017), not from
the shader, so that a test comparing the two catches a mistake in either.

One eye at a time; arrays are indexed [y, x] in any row order (the filter is symmetric).
`denoise()` takes the accumulated colour, its sample counts and luminance moments, and the
G-buffer guides, clamps outliers (`clamp_outliers`), filters, and returns the filtered colour;
pixels whose effect is not denoised come back as they went in.
"""
from __future__ import annotations

import numpy as np

from ..frame.passes.accumulate import DEMODULATE_FLOOR
from ..frame.passes.denoise import DEFAULTS, OUTLIER_MIN_WEIGHT, OUTLIER_RADIUS, OUTLIER_SIGMAS, DenoiseParams

LUMA = np.array([0.2126, 0.7152, 0.0722])
B3 = (3 / 8, 1 / 4, 1 / 16)  # the 5-tap B3 spline (1 4 6 4 1) / 16, by |offset|
MIN_TEMPORAL_SAMPLES = 4  # from this many samples the variance comes from the moments


def _finite(c: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(c).all(axis=-1, keepdims=True), c, 0.0)


def _shift(a: np.ndarray, dx: int, dy: int, fill=0):
    """b[y, x] = a[y + dy, x + dx], `fill` outside the image."""
    h, w = a.shape[:2]
    out = np.full_like(a, fill)
    ys, yd = slice(max(dy, 0), h + min(dy, 0)), slice(max(-dy, 0), h + min(-dy, 0))
    xs, xd = slice(max(dx, 0), w + min(dx, 0)), slice(max(-dx, 0), w + min(-dx, 0))
    out[yd, xd] = a[ys, xs]
    return out


def _snorm16(v):
    return np.round(np.clip(v, -1.0, 1.0) * 32767.0) / 32767.0


def octahedral_normal(n: np.ndarray) -> np.ndarray:
    """Unit normals as the guide stores them: octahedral encoding (Cigolle et al. 2014) in two
    snorm16, decoded (zero vectors, the background, become +z)."""
    n = np.asarray(n, np.float64)
    n = np.where((n * n).sum(-1, keepdims=True) > 0, n, [0.0, 0.0, 1.0])
    n = n / np.abs(n).sum(-1, keepdims=True)
    sign = np.where(n[..., :2] >= 0, 1.0, -1.0)
    e = np.where(n[..., 2:] >= 0, n[..., :2], (1.0 - np.abs(n[..., 1::-1])) * sign)
    e = _snorm16(e)
    d = np.concatenate([e, 1.0 - np.abs(e).sum(-1, keepdims=True)], -1)
    t = np.maximum(-d[..., 2:], 0.0)
    d[..., :2] += np.where(d[..., :2] >= 0, -t, t)
    return d / np.sqrt((d * d).sum(-1, keepdims=True))


class _Guides:
    """The edge-stop guides as the GPU packs them: view depth, octahedral snorm16 normal, base
    colour rounded to 8 bits, effect ID."""

    def __init__(self, albedo, normal, depth, effect, p: DenoiseParams):
        self.albedo = np.round(np.clip(albedo.astype(np.float64), 0.0, 1.0) * 255.0) / 255.0
        self.normal = octahedral_normal(normal)
        self.depth = depth.astype(np.float64)
        self.effect = effect.astype(np.int64)
        self.p = p
        self.grad = np.stack([self._gradient(1, 0), self._gradient(0, 1)], -1)

    def same(self, dx: int, dy: int) -> np.ndarray:
        """Whether the pixel (dx, dy) away exists and has the centre's effect."""
        return _shift(self.effect, dx, dy, fill=-1) == self.effect

    def _gradient(self, ox: int, oy: int) -> np.ndarray:
        z = self.depth
        hf, hb = self.same(ox, oy), self.same(-ox, -oy)
        f = np.where(hf, _shift(z, ox, oy) - z, 0.0)
        b = np.where(hb, z - _shift(z, -ox, -oy), 0.0)
        return np.where(hf & hb, np.where(np.abs(f) < np.abs(b), f, b), np.where(hf, f, b))

    def weight(self, dx: int, dy: int) -> np.ndarray:
        """Depth x normal x albedo edge-stop between each pixel and the one (dx, dy) away."""
        p = self.p
        z, zq = self.depth, _shift(self.depth, dx, dy)
        plane = np.abs(self.grad[..., 0] * dx + self.grad[..., 1] * dy)
        wz = np.exp(-np.abs(z - zq) / (p.sigma_depth * plane + 1e-3 * z + 1e-12))
        wn = np.maximum(0.0, (self.normal * _shift(self.normal, dx, dy)).sum(-1)) ** p.sigma_normal
        da = self.albedo - _shift(self.albedo, dx, dy)
        wa = np.exp(-(da * da).sum(-1) / p.sigma_albedo ** 2)
        return wz * wn * wa


def _demodulate(color, albedo):
    return _finite(color.astype(np.float64)) / np.maximum(albedo, DEMODULATE_FLOOR)


# the outlier clamp's statistics: the 5x5 neighbours
NEIGHBOURS = [(dx, dy) for dy in range(-OUTLIER_RADIUS, OUTLIER_RADIUS + 1)
              for dx in range(-OUTLIER_RADIUS, OUTLIER_RADIUS + 1) if dx or dy]


def clamp_outliers(illum, g: _Guides, sigmas: float = OUTLIER_SIGMAS) -> np.ndarray:
    """Demodulated colour with each pixel's luminance clamped to its 5x5 neighbours' mean + `sigmas`
    standard deviations: the neighbours of its effect weighted by the depth, normal and albedo
    edge-stops, the brightest of them left out (a firefly's neighbour may be another). A pixel
    whose neighbours weigh less than OUTLIER_MIN_WEIGHT in all stays as it is; a clamped one
    keeps its chroma."""
    lum = illum @ LUMA
    same = np.stack([g.same(dx, dy) for dx, dy in NEIGHBOURS])
    w = np.stack([np.where(same[k], g.weight(dx, dy), 0.0) for k, (dx, dy) in enumerate(NEIGHBOURS)])
    lq = np.stack([_shift(lum, dx, dy) for dx, dy in NEIGHBOURS])
    brightest = np.argmax(np.where(same, lq, -np.inf), axis=0)  # of the effect's, whatever its weight
    w = np.where(np.arange(len(NEIGHBOURS))[:, None, None] == brightest, 0.0, w)
    sw = w.sum(0)
    judged = sw >= OUTLIER_MIN_WEIGHT
    sw = np.where(judged, sw, 1.0)
    mean = (w * lq).sum(0) / sw
    sd = np.sqrt((w * (lq - mean) ** 2).sum(0) / sw)
    bound = mean + sigmas * sd
    over = judged & (lum > bound)
    return illum * np.where(over, bound / np.where(over, lum, 1.0), 1.0)[..., None]


def variance(illum, samples, moments, g: _Guides) -> np.ndarray:
    """The variance of each pixel's demodulated luminance: of the mean of its samples from
    MIN_TEMPORAL_SAMPLES on, else the edge-weighted spread of `illum` (the demodulated colour)
    over its 7x7 neighbourhood."""
    m1, m2 = moments[..., 0].astype(np.float64), moments[..., 1].astype(np.float64)
    temporal = np.maximum(m2 - m1 * m1, 0.0) / np.maximum(samples, 1.0)
    lum = illum @ LUMA
    sw, s1, s2 = np.zeros_like(lum), np.zeros_like(lum), np.zeros_like(lum)
    for dy in range(-3, 4):
        for dx in range(-3, 4):
            w = np.ones_like(lum) if dx == dy == 0 else g.weight(dx, dy)
            w = np.where(g.same(dx, dy), w, 0.0)
            lq = _shift(lum, dx, dy)
            sw += w
            s1 += w * lq
            s2 += w * lq * lq
    s1, s2 = s1 / sw, s2 / sw
    spatial = np.maximum(s2 - s1 * s1, 0.0)
    return np.where(samples >= MIN_TEMPORAL_SAMPLES, temporal, spatial)


def atrous_iteration(illum, var, step: int, g: _Guides):
    """One à-trous iteration: (filtered demodulated colour, its variance)."""
    vs, vw = np.zeros_like(var), np.zeros_like(var)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            k = (0.5 if dx == 0 else 0.25) * (0.5 if dy == 0 else 0.25)
            ok = g.same(dx, dy)
            vs += np.where(ok, k * _shift(var, dx, dy), 0.0)
            vw += np.where(ok, k, 0.0)
    lum = illum @ LUMA
    sigma_l = g.p.sigma_luminance * np.sqrt(np.maximum(vs / vw, 0.0)) + 1e-10
    w0 = B3[0] * B3[0]
    sum_w = np.full_like(var, w0)
    sum_c = w0 * illum
    sum_v = w0 * w0 * var
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            if dx == dy == 0:
                continue
            ox, oy = dx * step, dy * step
            ok = g.same(ox, oy)
            cq, vq = _shift(illum, ox, oy), _shift(var, ox, oy)
            wl = np.exp(-np.abs(lum - cq @ LUMA) / sigma_l)
            w = np.where(ok, B3[abs(dx)] * B3[abs(dy)] * g.weight(ox, oy) * wl, 0.0)
            sum_w += w
            sum_c += w[..., None] * cq
            sum_v += w * w * vq
    return sum_c / sum_w[..., None], sum_v / (sum_w * sum_w)


def denoise(color, samples, moments, albedo, normal, depth, effect, denoised_ids, iterations: int = 4,
            params: DenoiseParams = DEFAULTS, outlier_sigmas: float | None = OUTLIER_SIGMAS) -> np.ndarray:
    """Filter one eye. color (H, W, 3) accumulated linear colour; samples (H, W) its sample
    counts; moments (H, W, 2) mean demodulated luminance and its square; albedo (H, W, 3) base
    colour; normal (H, W, 3); depth (H, W) view depth; effect (H, W) effect IDs; denoised_ids
    the effect IDs to filter; outlier_sigmas the clamp's bound (None: no clamp, to compare).
    Returns (H, W, 3) float64."""
    g = _Guides(albedo, normal, depth, effect, params)
    albedo = albedo.astype(np.float64)  # demodulation: the G-buffer's own base colour
    illum = _demodulate(color, albedo)
    if outlier_sigmas is not None:
        illum = clamp_outliers(illum, g, outlier_sigmas)
    var = variance(illum, np.asarray(samples, np.float64), moments, g)
    for i in range(iterations):
        illum, var = atrous_iteration(illum, var, 1 << i, g)
    listed = np.isin(g.effect, list(denoised_ids))
    out = illum * np.maximum(albedo, DEMODULATE_FLOOR)
    return np.where(listed[..., None], out, _finite(color.astype(np.float64)))
