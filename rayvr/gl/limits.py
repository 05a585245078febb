"""The ranges of the numbers rayvr hands to the GPU, where they become float32 (max 3.4e38; GPUs
flush numbers below 1.2e-38 to zero). A value that is finite in float64 but overflows there, or
a meaningful small one that flushes to zero, renders a blank frame; every setting that reaches the
shaders is checked against its range here, once, when it is given (frame/cameras/rig.py, frame/cameras/, app/views.py),
and uploads go through `to_float32`, which refuses what would still overflow.
"""
from __future__ import annotations

import math

import numpy as np

FLOAT32_MAX = float(np.finfo(np.float32).max)
FLOAT32_NORMAL_MIN = float(np.finfo(np.float32).tiny)  # smaller numbers flush to zero on GPUs

# Farthest a camera (and a thin lens's ray origins) may be from the scene's origin along an axis,
# and the largest IPD: the shaders square distances (lengths, ray-box and ray-sphere maths), and
# (2e18)^2 leaves float32 room. Beyond it no scene (coordinates up to 1e8) covers a pixel anyway.
MAX_CAMERA_COORDINATE = 1e18
# near, far, convergence. The depth maths (near / distance, near * far / (far - near))
# stays finite below it.
MAX_DISTANCE = 1e30
# Farthest focus distance of a thin lens: the focal point of a ray at a frustum's edge (tangent up
# to 1e5) lies 1.4e5 focus distances away, and the shaders square that distance. Measured with a
# 90-degree dof camera: 1e19 renders, 1e20 is all background; 1e12 leaves room for 1e5 tangents.
MAX_FOCUS_DISTANCE = 1e12
# Shortest near or focus distance: reversed-Z depth is near / distance, which must stay a normal
# float32 for any distance up to MAX_CAMERA_COORDINATE; a focus point's squared distance likewise.
MIN_DISTANCE = 1e-18


def interval(lo: float, hi: float, lo_open: bool = False, hi_open: bool = False) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


def check_range(what: str, value, lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False) -> float:
    """`value` as a float when it is a finite number in the interval from lo to hi (ends open as
    asked), else ValueError naming `what` and its legal range."""
    legal = interval(lo, hi, lo_open, hi_open)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} must be a number in {legal}, got {value!r}")
    v = float(value)
    inside = math.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not inside:
        raise ValueError(f"{what} must be in {legal}, got {value!r}")
    return v


def to_float32(what: str, values) -> np.ndarray:
    """`values` as a float32 array for an upload, or ValueError naming `what` where a value is not
    finite or overflows float32 (the last guard: the settings' own ranges are checked earlier)."""
    a = np.asarray(values, np.float64)
    bad = ~(np.abs(a) <= FLOAT32_MAX)  # NaN too
    if bad.any():
        raise ValueError(f"{what}: {a[bad][0]:g} does not fit the GPU's float32 (at most {FLOAT32_MAX:.3g})")
    return a.astype(np.float32)
