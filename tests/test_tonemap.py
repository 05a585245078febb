"""Exposure, tonemappers and sRGB encoding (glsl/common/color.glsl, glsl/shade/tonemap.comp) against
numpy written from the published curves, on a wall of emissive cells whose radiances span five
decades (so every part of each curve is used: toe, shoulder and the clamp)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays
from rayvr.quality.tonemap import CURVES, aces_narkowicz, to_ldr
from rayvr.quality.metrics import srgb_encode as srgb

COLS, ROWS = 8, 6


def test_reference_curves_at_known_points():
    """The numpy curves themselves, at values worked out by hand."""
    assert aces_narkowicz(np.array([0.0]))[0] == 0.0
    # 0.18: (0.18 * (2.51 * 0.18 + 0.03)) / (0.18 * (2.43 * 0.18 + 0.59) + 0.14) = 0.086724 / 0.324932
    assert aces_narkowicz(np.array([0.18]))[0] == pytest.approx(0.086724 / 0.324932, rel=1e-12)
    assert aces_narkowicz(np.array([1.0]))[0] == pytest.approx(2.54 / 3.16, rel=1e-12)
    assert aces_narkowicz(np.array([1e4]))[0] == 1.0  # the fit tends to 2.51 / 2.43 > 1: clamped
    assert srgb(np.array([0.5]))[0] == pytest.approx(1.055 * 0.5 ** (1 / 2.4) - 0.055)
    assert srgb(np.array([0.002]))[0] == pytest.approx(12.92 * 0.002)


@pytest.fixture(scope="module")
def cells():
    """A wall of COLS x ROWS emissive cells (base colour black, no light, no ambient, black
    background: the linear colour is the emission), each channel at its own level, 1e-3 .. 60."""
    parts, mats = [], []
    levels = np.geomspace(1e-3, 60.0, COLS * ROWS)
    for k in range(COLS * ROWS):
        i, j = k % COLS, k // COLS
        parts.append(quad((i - (COLS - 1) / 2, (ROWS - 1) / 2 - j, 0.0), (0.5, 0, 0), (0, 0.5, 0)))
        a = float(levels[k])
        # channels in a different order per cell: every level reaches every channel somewhere
        e = np.roll([a, a * 0.31, min(a * 3.7, 200.0)], k % 3)
        mats.append(Material(f"cell{k}", base_color=(0, 0, 0, 1), emission=tuple(float(x) for x in e)))
    v, f, part = merge(*parts)
    scene = from_arrays(v, f, triangle_material=part, materials=mats, lights=[Light("point", intensity=0.0)])
    rig = StereoRig(Pose.look_at((0.0, 0.0, 7.0), (0.0, 0.0, 0.0)), ipd=0.0, fov_y=45, size=(48, 36))
    return scene, rig, np.array([m.emission for m in mats])


@pytest.mark.parametrize("tonemapper, exposure", [("aces", 1.0), ("aces", 0.21), ("aces", 3.3),
                                                  ("reinhard", 1.0), ("reinhard", 2.7), ("clamp", 0.45)])
def test_8_bit_colour_is_the_curve_of_the_exposed_linear_colour(gl, cells, tonemapper, exposure):
    scene, rig, emission = cells
    settings = RenderSettings(tonemapper=tonemapper, exposure=exposure, ambient=(0, 0, 0), background=(0, 0, 0))
    with Renderer(scene, gl=gl, settings=settings) as r:
        frame = r.render(rig, eyes="left", aux=("hdr", "material", "depth"))
    eye = frame.left
    hdr, on = eye.aux["hdr"].astype(np.float64), eye.depth > 0
    assert on.mean() > 0.5
    # The linear colour is each cell's emission (to half-float precision): the input is known.
    want_hdr = emission[eye.aux["material"][on]]
    assert np.allclose(hdr[on], want_hdr, rtol=1e-3, atol=1e-6)
    assert (hdr[~on] == 0).all()
    # ... and the 8-bit colour is exposure, then the curve, then sRGB, rounded.
    want = srgb(CURVES[tonemapper](hdr * exposure)) * 255.0
    got = eye.color.astype(np.float64)
    err = np.abs(got - want)
    assert err.max() <= 0.6, f"{tonemapper} x{exposure}: off by up to {err.max():.2f} levels"
    # The host's transform (the bench reference's, from averaged radiance) stores the same levels.
    assert np.abs(to_ldr(eye.aux["hdr"], tonemapper, exposure).astype(int) - eye.color).max() <= 1
    # Every part of the curve is exercised: dark, mid and saturated pixels.
    assert (want < 20).any() and ((want > 60) & (want < 200)).any() and (want > 254).any()
