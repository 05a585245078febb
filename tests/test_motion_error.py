"""Errors in motion (rayvr/quality/motion_error.py) on sequences whose answer is known: a bias that
moves with the scene flickers nothing, fresh noise flickers by sqrt(2) of its spread, a frame
behind the reference lags by its delay, and per-frame FLIP is the still metric frame by frame."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rayvr.quality.motion_error import flicker, lag_frames, per_frame_flip
from rayvr.quality.metrics import flip


def moving_scene(n=8, size=(24, 32)):
    """Display-valued frames of a gradient sliding a pixel a frame."""
    y, x = np.mgrid[0:size[0], 0:size[1]]
    return [np.repeat((0.2 + 0.6 * ((x + k) % size[1]) / size[1])[..., None], 3, axis=2).astype(np.float32)
            for k in range(n)]


def test_a_bias_that_moves_with_the_scene_flickers_nothing():
    refs = moving_scene()
    biased = [r * 0.9 + 0.03 for r in refs]  # a fixed error: the same each frame, relative to the scene
    got = flicker(refs, biased, float_encoding="srgb")
    # the change is the reference's change times 0.9: only 10 % of the scene's own change differs
    expect = [0.1 * np.abs(refs[k + 1] - refs[k]).mean() for k in range(len(refs) - 1)]
    np.testing.assert_allclose(got, expect, rtol=1e-5)
    assert flicker(refs, [r.copy() for r in refs], float_encoding="srgb").max() == 0.0


def test_fresh_noise_flickers_by_its_spread_times_sqrt_two():
    rng = np.random.default_rng(4)
    refs = [np.full((64, 64, 3), 0.5, np.float32)] * 6
    sigma = 0.02
    noisy = [r + rng.normal(0, sigma, r.shape).astype(np.float32) for r in refs]
    got = flicker(refs, noisy, float_encoding="srgb")
    # |N(0, 2 sigma^2)| has mean sqrt(2) sigma sqrt(2 / pi)
    np.testing.assert_allclose(got, math.sqrt(2) * sigma * math.sqrt(2 / math.pi), rtol=0.05)
    same_noise = [refs[0] + (noisy[0] - refs[0])] * 6  # the same noise every frame: no shimmer
    assert flicker(refs, same_noise, float_encoding="srgb").max() == pytest.approx(0.0, abs=1e-7)


def test_a_frame_behind_the_reference_lags_by_its_delay():
    step = np.r_[np.zeros(10), np.linspace(0, 1, 6), np.ones(14)]  # a light fading in
    for delay in (0, 1, 3):
        late = np.r_[np.zeros(delay), step[:len(step) - delay]]
        assert lag_frames(step, late) == delay


def test_per_frame_flip_is_the_still_metric_frame_by_frame():
    refs = moving_scene(4)
    frames = [np.clip(r + 0.05 * k, 0, 1) for k, r in enumerate(refs)]
    got = per_frame_flip(refs, frames, float_encoding="srgb")
    assert got[0] == 0.0 and (np.diff(got) > 0).all()
    assert got[2] == flip(refs[2], frames[2], float_encoding="srgb")


def test_bad_sequences_are_refused():
    refs = moving_scene(3)
    with pytest.raises(ValueError, match="one reference a frame"):
        flicker(refs, refs[:2])
    with pytest.raises(ValueError, match="at least two frames"):
        flicker(refs[:1], refs[:1])
    with pytest.raises(ValueError, match="the frames differ in size"):
        flicker(refs, [refs[0], refs[1], refs[2][:10]], float_encoding="srgb")
