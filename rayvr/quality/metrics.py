"""Image error metrics for the speed <-> accuracy trade: mean FLIP, PSNR and SSIM.

Inputs are HxWx3 arrays, reference first:

* ``uint8``  -> sRGB-encoded display values (what ``fbo.read()`` of an RGBA8/SRGB8 target gives).
* float      -> **linear** RGB (what an RGBA16F/32F target holds). It is clipped to [0, 1] and
  encoded with the sRGB transfer function. Pass ``float_encoding="srgb"`` if your floats are
  already sRGB-encoded (they are then only clipped).

Every metric is computed on the sRGB-encoded values in [0, 1]: that is what the viewer sees, what
FLIP's LDR mode expects, and what PSNR/SSIM are conventionally reported on. HDR values above 1 are
clipped, so these are LDR (display-referred) errors.

Masks are boolean HxW arrays selecting the pixels an effect touches. FLIP and SSIM are spatial
(they look at neighbourhoods), so their maps are always computed on the whole image and only the
*average* is restricted to the mask; PSNR uses the MSE over the masked pixels. An empty mask is an
error (a mean over no pixels has no value).

FLIP needs ``flip-evaluator`` (the optional ``bench`` extra, imported lazily); PSNR and SSIM are
plain numpy.
"""
from __future__ import annotations

import math

import numpy as np

from ..util.extras import require

# Approximate per-eye horizontal field of view (degrees) and eye-buffer width (pixels) of common
# headsets, from vendor specs and reviews. Only used to pick a pixels-per-degree for FLIP.
HEADSETS: dict[str, tuple[float, int]] = {
    "index": (108.0, 1440),  # Valve Index: 1440x1600 per eye (the 2x1440x1600 target)
    "quest3": (110.0, 2064),  # Meta Quest 3: 2064x2208 per eye
}
DEFAULT_HEADSET = "index"

# Wang et al. 2004 SSIM constants: Gaussian window sigma 1.5 (11x11), K1 = 0.01, K2 = 0.03.
SSIM_SIGMA = 1.5
SSIM_RADIUS = 5
SSIM_K1 = 0.01
SSIM_K2 = 0.03


def ppd_for_headset(fov_deg: float, width_px: int, at: str = "mean") -> float:
    """Pixels per degree of an image `width_px` wide spread over `fov_deg` degrees horizontally.

    ``at="mean"`` (default) is width / fov, the average over the field of view and the figure
    headset specs quote (lens distortion spreads pixels roughly evenly over the view).
    ``at="center"`` is the density at the centre of a pinhole (perspective) eye buffer:
    (width / 2) / tan(fov / 2) pixels per radian, converted to degrees. It is *lower* than the
    mean, because a pinhole image spends more pixels per degree towards its edges.
    """
    if not (0.0 < fov_deg < 180.0):
        raise ValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    if width_px <= 0:
        raise ValueError(f"width_px must be positive, got {width_px}")
    if at == "mean":
        return float(width_px) / float(fov_deg)
    if at == "center":
        return (width_px / 2.0) / math.tan(math.radians(fov_deg) / 2.0) * (math.pi / 180.0)
    raise ValueError(f"at must be 'mean' or 'center', got {at!r}")


# Index-class headset: 1440 px over ~108 degrees, about 13.3 ppd (FLIP's own default, 67 ppd,
# is a desktop monitor at arm's length and would under-weight errors a headset makes visible).
DEFAULT_PPD = ppd_for_headset(*HEADSETS[DEFAULT_HEADSET])


# --------------------------------------------------------------------------------------------
# Input handling


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> sRGB-encoded [0, 1] (IEC 61966-2-1 transfer function)."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def to_display(img: np.ndarray, name: str = "image", float_encoding: str = "linear") -> np.ndarray:
    """Validate one HxWx3 image and return its sRGB-encoded values in [0, 1] as float64."""
    img = np.asarray(img)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"{name} must be HxWx3, got shape {img.shape}")
    if img.shape[0] == 0 or img.shape[1] == 0:
        raise ValueError(f"{name} is empty (shape {img.shape})")
    if img.dtype == np.uint8:
        return img.astype(np.float64) / 255.0
    if not np.issubdtype(img.dtype, np.floating):
        raise TypeError(f"{name} must be uint8 (sRGB) or float (linear), got dtype {img.dtype}")
    x = img.astype(np.float64)
    if not np.isfinite(x).all():
        bad = "NaN" if np.isnan(x).any() else "inf"
        raise ValueError(f"{name} contains {bad} values")
    if float_encoding == "linear":
        return srgb_encode(x)
    if float_encoding == "srgb":
        return np.clip(x, 0.0, 1.0)
    raise ValueError(f"float_encoding must be 'linear' or 'srgb', got {float_encoding!r}")


def _check_mask(mask, shape) -> np.ndarray | None:
    if mask is None:
        return None
    mask = np.asarray(mask)
    if mask.dtype != bool:
        raise TypeError(f"mask must be a boolean array, got dtype {mask.dtype}")
    if mask.shape != tuple(shape[:2]):
        raise ValueError(f"mask shape {mask.shape} does not match image shape {tuple(shape[:2])}")
    if not mask.any():
        raise ValueError("mask selects no pixels; the error over an empty region is undefined")
    return mask


def _prepare(ref, test, mask, float_encoding):
    r = to_display(ref, "reference", float_encoding)
    t = to_display(test, "test", float_encoding)
    if r.shape != t.shape:
        raise ValueError(f"shape mismatch: reference {r.shape} vs test {t.shape}")
    return r, t, _check_mask(mask, r.shape)


def _masked_mean(m: np.ndarray, mask: np.ndarray | None) -> float:
    return float(m.mean() if mask is None else m[mask].mean())


# --------------------------------------------------------------------------------------------
# Metric maps (on display values in [0, 1])


def _flip_map(r: np.ndarray, t: np.ndarray, ppd: float) -> np.ndarray:
    flip_evaluator = require("flip_evaluator", "FLIP")
    if not ppd > 0:
        raise ValueError(f"ppd must be positive, got {ppd}")
    err, _, _ = flip_evaluator.evaluate(
        np.ascontiguousarray(r, dtype=np.float32),
        np.ascontiguousarray(t, dtype=np.float32),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        computeMeanError=False,
        parameters={"ppd": float(ppd)},
    )
    return np.asarray(err, dtype=np.float64).reshape(r.shape[:2])


def _blur_axis(x: np.ndarray, w: np.ndarray, axis: int, pad: bool = True) -> np.ndarray:
    """Convolve with the symmetric kernel `w` along `axis` (0 or 1).

    pad=True mirror-pads the borders ('symmetric': d c b a | a b c d, the usual choice for
    SSIM) and keeps the size; pad=False returns only the rows/columns with a full window.
    """
    r = len(w) // 2
    if pad:
        widths = [(0, 0)] * x.ndim
        widths[axis] = (r, r)
        x = np.pad(x, widths, mode="symmetric")
    p = np.moveaxis(x, axis, 0)  # slice along the first axis: cheap views
    n = p.shape[0] - 2 * r
    out = w[r] * p[r:r + n]
    tmp = np.empty_like(out)
    for i in range(r):  # the kernel is symmetric: add mirrored taps, then weight once
        np.add(p[i:i + n], p[2 * r - i:2 * r - i + n], out=tmp)
        tmp *= w[i]
        out += tmp
    return np.moveaxis(out, 0, axis)


def _ssim_kernel(dtype) -> np.ndarray:
    k = np.arange(-SSIM_RADIUS, SSIM_RADIUS + 1, dtype=np.float64)
    w = np.exp(-0.5 * (k / SSIM_SIGMA) ** 2)
    return (w / w.sum()).astype(dtype)


def _ssim_map(r: np.ndarray, t: np.ndarray, rows_per_strip: int = 32) -> np.ndarray:
    """Per-pixel SSIM averaged over the three channels (data range 1).

    Works in float32 on values shifted to [-0.5, 0.5] (variance and covariance do not change
    with a shift, and centring keeps E[x^2] - E[x]^2 accurate to ~1e-7), one strip of rows at a
    time so the working set stays in cache; together ~3x faster than one float64 pass.
    """
    h = r.shape[0]
    rad = SSIM_RADIUS
    w = _ssim_kernel(np.float32)
    # Mirror-pad the rows once; each strip then reads its halo from the padded image.
    rows = [(rad, rad), (0, 0), (0, 0)]
    rp = np.pad((r - 0.5).astype(np.float32), rows, mode="symmetric")
    tp = np.pad((t - 0.5).astype(np.float32), rows, mode="symmetric")
    c1 = SSIM_K1 ** 2
    c2 = SSIM_K2 ** 2
    out = np.empty(r.shape[:2], dtype=np.float64)
    for y0 in range(0, h, rows_per_strip):
        y1 = min(h, y0 + rows_per_strip)
        a, b = rp[y0:y1 + 2 * rad], tp[y0:y1 + 2 * rad]
        stack = np.concatenate([a, b, a * a, b * b, a * b], axis=2)
        s = _blur_axis(_blur_axis(stack, w, 0, pad=False), w, 1).astype(np.float64)
        mr, mt, rr, tt, rt = np.split(s, 5, axis=2)
        vr = rr - mr * mr
        vt = tt - mt * mt
        cov = rt - mr * mt
        mr += 0.5
        mt += 0.5
        num = (2 * mr * mt + c1) * (2 * cov + c2)
        den = (mr * mr + mt * mt + c1) * (vr + vt + c2)
        out[y0:y1] = (num / den).mean(axis=2)
    return out


# --------------------------------------------------------------------------------------------
# Public metrics


def flip(ref, test, mask=None, ppd: float = DEFAULT_PPD, float_encoding: str = "linear") -> float:
    """Mean LDR FLIP error (0 = identical, 1 = maximal) at `ppd` pixels per degree."""
    r, t, mask = _prepare(ref, test, mask, float_encoding)
    return _masked_mean(_flip_map(r, t, ppd), mask)


def flip_map(ref, test, ppd: float = DEFAULT_PPD, float_encoding: str = "linear") -> np.ndarray:
    """Per-pixel LDR FLIP error map (HxW float64), e.g. to save as a figure."""
    r, t, _ = _prepare(ref, test, None, float_encoding)
    return _flip_map(r, t, ppd)


def _psnr(r, t, mask) -> float:
    d = (r - t) ** 2
    mse = float(d.mean() if mask is None else d[mask].mean())
    # Identical images: the ratio is unbounded; report +inf rather than dividing by zero.
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def psnr(ref, test, mask=None, float_encoding: str = "linear") -> float:
    """PSNR in dB with a peak of 1 (255 for uint8); +inf for identical pixels, never NaN."""
    r, t, mask = _prepare(ref, test, mask, float_encoding)
    return _psnr(r, t, mask)


def ssim(ref, test, mask=None, float_encoding: str = "linear") -> float:
    """Mean SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03).

    Computed per channel and averaged. Unlike skimage's scalar result, the border pixels are
    kept (mirror padding) so that a full mask equals the unmasked value.
    """
    r, t, mask = _prepare(ref, test, mask, float_encoding)
    return _masked_mean(_ssim_map(r, t), mask)


def compare(
    ref,
    test,
    mask=None,
    ppd: float = DEFAULT_PPD,
    metrics=("flip", "psnr", "ssim"),
    float_encoding: str = "linear",
) -> dict:
    """All requested metrics at once, ready to be a benchmark row.

    Keys are the metric names over the whole image; with a mask, ``<metric>_mask`` over the mask
    and ``mask_pixels`` are added. Each map is computed once.
    """
    unknown = set(metrics) - {"flip", "psnr", "ssim"}
    if unknown:
        raise ValueError(f"unknown metrics {sorted(unknown)}; choose from flip, psnr, ssim")
    r, t, mask = _prepare(ref, test, mask, float_encoding)
    out: dict = {}
    maps = {}
    if "flip" in metrics:
        maps["flip"] = _flip_map(r, t, ppd)
    if "ssim" in metrics:
        maps["ssim"] = _ssim_map(r, t)
    for m in metrics:
        out[m] = _psnr(r, t, None) if m == "psnr" else _masked_mean(maps[m], None)
        if mask is not None:
            out[m + "_mask"] = _psnr(r, t, mask) if m == "psnr" else _masked_mean(maps[m], mask)
    if mask is not None:
        out["mask_pixels"] = int(mask.sum())
    return out
