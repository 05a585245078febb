"""Sampled effects must not show different noise in the two eyes (it shimmers in a headset):
samples are seeded from the surface point, so with IPD 0 both eyes are identical, pixel for pixel,
and a point seen by both eyes draws the same samples."""
from __future__ import annotations

import numpy as np

from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import load

NOISY = {"default": "shadows", "params": {"shadows": {"area_samples": 1}},
         "materials": {"gold": {"effect": "glossy", "samples": 1}, "floor": {"effect": "glossy", "samples": 1},
                       "ceiling": {"effect": "path", "samples": 1}, "wall*": {"effect": "path", "samples": 1},
                       "mirror*": {"effect": "reflections"}}}


def _render(gl, rig, seed=0):
    scene = load()
    with Renderer(scene, parse_config(NOISY, "<noisy>"), gl=gl, settings=RenderSettings(seed=seed)) as r:
        frame = r.render(rig, aux=("hdr",))
    return frame.left.aux["hdr"], frame.right.aux["hdr"]


def test_ipd_zero_gives_identical_eyes_with_sampled_effects(gl):
    """Every sampled effect of the ladder (soft shadows, glossy, path) in one view."""
    from rayvr.frame.effects import EFFECTS

    scene = load()
    used = {e for e in ("shadows", "glossy", "path", "reflections") if e in EFFECTS}
    names = scene.material_names()
    assert {"ceiling", "gold", "floor"} <= set(names) and used == {"shadows", "glossy", "path", "reflections"}
    rig = StereoRig.for_scene(scene, size=(48, 36), ipd=0.0)
    left, right = _render(gl, rig)
    assert np.array_equal(left, right)
    # ... and the samples are really random: another seed changes the noise.
    other, _ = _render(gl, rig, seed=7)
    assert not np.array_equal(left, other)


def test_a_surface_point_draws_the_same_samples_from_either_eye(gl):
    """Both eyes on the same spot, looking the same way, but the right eye's frustum shifted by
    a whole number of pixels: each right pixel then sees the point a left pixel sees, so the images
    must agree where both see it, noise included (per-pixel seeds would not)."""
    scene = load()
    w, h, shift = 48, 36, 5
    t = np.tan(np.radians(45.0))
    width = 2 * t * w / h
    step = width / w
    left = (-t * w / h, t * w / h, -t, t)
    right = (left[0] + shift * step, left[1] + shift * step, -t, t)
    pose = StereoRig.for_scene(scene).pose
    rig = StereoRig(Pose(pose.position, pose.rotation), ipd=0.0, size=(w, h),
                    eye_tangents={"left": left, "right": right})
    a, b = _render(gl, rig)
    a7, _ = _render(gl, rig, seed=7)

    def agree(x, y):  # fraction of pixels equal to float16 rounding
        return float((np.abs(x - y).max(-1) <= 1e-3 * np.maximum(np.abs(x).max(-1), 1.0)).mean())

    # Right column x sees what left column x + shift sees. The two eyes' rays to a point differ in
    # the last bits (different tangents), so a point within that of a cell boundary may seed from
    # the neighbouring cell: 3 % of pixels here.
    stereo = agree(a[:, shift:], b[:, :-shift])
    assert stereo >= 0.9, stereo
    # What a different sample sequence looks like: most of this view is noisy.
    assert agree(a, a7) < 0.5, agree(a, a7)
