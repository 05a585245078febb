"""The error a moving user sees: frames along a head trajectory (rayvr/bench/trajectories.py)
judged against each frame's own converged reference.

- `per_frame_flip`: mean FLIP of every frame against its reference (quality/metrics.py), the
  still-frame error, frame by frame.
- `flicker`: how much the frame-to-frame change differs from the reference's frame-to-frame change,
  per transition: the mean absolute difference of the two changes in display values (sRGB in
  [0, 1], as the metrics see them). A frame with a fixed error (a bias, a blur) that moves with the
  scene flickers nothing; noise drawn anew each frame flickers by about sqrt(2) of its spread, the
  shimmer a headset shows; a frame that lags behind the reference flickers where the scene changes.
- `lag_frames`: by how many frames a signal of the frames (for instance their mean luminance
  through a lit change) trails the references' signal: the shift that best aligns their changes.

The inputs are sequences of HxWx3 images, reference first, as metrics.py takes them.
"""
from __future__ import annotations

import numpy as np

from .metrics import flip, to_display


def _display(images, name: str, float_encoding: str) -> list[np.ndarray]:
    out = [to_display(np.asarray(im), name, float_encoding) for im in images]
    if len({im.shape for im in out}) > 1:
        raise ValueError(f"{name}: the frames differ in size: {sorted({im.shape for im in out})}")
    return out


def _check(references, frames) -> None:
    if len(references) != len(frames):
        raise ValueError(f"{len(frames)} frames for {len(references)} references: one reference a frame")
    if len(frames) < 2:
        raise ValueError("a motion error needs at least two frames")


def per_frame_flip(references, frames, float_encoding: str = "linear", **kw) -> np.ndarray:
    """Mean FLIP of frame k against reference k, for every k."""
    _check(references, frames)
    return np.array([flip(r, f, float_encoding=float_encoding, **kw) for r, f in zip(references, frames)])


def flicker(references, frames, float_encoding: str = "linear") -> np.ndarray:
    """Per transition k -> k+1: mean over pixels and channels of |(F_k+1 - F_k) - (R_k+1 - R_k)|
    in display values."""
    _check(references, frames)
    r, f = _display(references, "references", float_encoding), _display(frames, "frames", float_encoding)
    if r[0].shape != f[0].shape:
        raise ValueError(f"frames are {f[0].shape[:2]}, references {r[0].shape[:2]}")
    return np.array([np.abs((f[k + 1] - f[k]) - (r[k + 1] - r[k])).mean() for k in range(len(f) - 1)])


def lag_frames(reference_signal, frame_signal, max_lag: int = 16) -> int:
    """The shift s in [0, max_lag] for which the frames' changes, moved s frames earlier, best match
    the references' changes (least squares): how many frames the frames trail."""
    a = np.diff(np.asarray(reference_signal, dtype=np.float64))
    b = np.diff(np.asarray(frame_signal, dtype=np.float64))
    if a.shape != b.shape or len(a) < 2:
        raise ValueError("the two signals need the same length, at least three values")
    costs = []
    for s in range(min(max_lag, len(a) - 1) + 1):
        costs.append(np.mean((b[s:] - a[:len(a) - s]) ** 2))
    return int(np.argmin(costs))
