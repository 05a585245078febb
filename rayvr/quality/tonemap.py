"""The display transform on the host: exposure, the tonemapper's published curve, sRGB encoding
and 8 bits, as glsl/common/color.glsl and glsl/shade/tonemap.comp do it on the GPU. For images
made on the host from linear radiance: the bench reference is the mean of two renders' radiance
(rayvr/quality/measure.py). tests/test_tonemap.py holds the GPU to these curves."""
from __future__ import annotations

import numpy as np

from ..gl.gpu_layout import TONEMAPPERS
from .metrics import srgb_encode


def aces_narkowicz(x):
    """Krzysztof Narkowicz 2015, "ACES Filmic Tone Mapping Curve": a rational fit of the ACES RRT+ODT."""
    a, b, c, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    return np.clip((x * (a * x + b)) / (x * (c * x + d) + e), 0.0, 1.0)


CURVES = {
    "aces": aces_narkowicz,
    "reinhard": lambda x: x / (1.0 + x),
    "clamp": lambda x: np.clip(x, 0.0, 1.0),
}
assert set(CURVES) == set(TONEMAPPERS), "a tonemapper of the GPU without its curve here"


def display_values(linear: np.ndarray, tonemapper: str = "aces", exposure: float = 1.0) -> np.ndarray:
    """HxWx3 (or more channels: the first 3 are taken) linear radiance -> sRGB-encoded [0, 1], float64."""
    if tonemapper not in CURVES:
        raise ValueError(f"unknown tonemapper {tonemapper!r}; choose from {', '.join(CURVES)}")
    x = np.asarray(linear, np.float64)[..., :3] * float(exposure)
    return srgb_encode(CURVES[tonemapper](x))


def to_ldr(linear: np.ndarray, tonemapper: str = "aces", exposure: float = 1.0) -> np.ndarray:
    """The 8-bit image the GPU's tonemap pass would store for `linear` (to one level: float32 there)."""
    return np.rint(display_values(linear, tonemapper, exposure) * 255.0).astype(np.uint8)
