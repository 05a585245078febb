"""The denoiser's outlier clamp (glsl/post/denoise.comp stage 4; numpy twin clamp_outliers in
rayvr/reference/denoise.py): a firefly, one pixel far brighter than its 5x5 neighbours on its
surface, is clamped before the à-trous filter, by the GPU and numpy alike; a highlight wider than
a pixel, a one-pixel bright line, a smooth peak and a pixel of another surface are kept; and
`rayvr capture`'s default frame (denoised) has no isolated bright pixels where the raw one has many."""
from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.effects import EFFECTS
from rayvr.reference.denoise import DEFAULTS, LUMA, _Guides, clamp_outliers, denoise
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config

GLOSSY = EFFECTS["glossy"].id
N = 32


def _flat(noise: float = 0.3, seed: int = 0, n: int = N):
    """A plane seen head-on, one effect, grey albedo, lit at 1.0 with multiplicative noise (sd
    `noise`): the denoiser's inputs as keywords of `denoise`, and its illumination."""
    rng = np.random.default_rng(seed)
    light = np.ones((n, n)) if noise == 0 else rng.gamma(1 / noise ** 2, noise ** 2, (n, n))
    albedo = np.full((n, n, 3), 0.5)
    normal = np.zeros((n, n, 3))
    normal[..., 2] = 1.0
    inputs = dict(color=light[..., None] * albedo, samples=np.ones((n, n)), moments=np.zeros((n, n, 2)),
                  albedo=albedo, normal=normal, depth=np.full((n, n), 2.0), effect=np.full((n, n), GLOSSY))
    return inputs, light


def _clamped(inputs, light):
    """clamp_outliers of the plane lit by `light` (grey: its demodulated illumination in each channel)."""
    g = _Guides(inputs["albedo"], inputs["normal"], inputs["depth"], inputs["effect"], DEFAULTS)
    out = clamp_outliers(np.repeat(light[..., None], 3, -1), g)
    assert np.array_equal(out[..., 0], out[..., 2])  # a clamped colour keeps its chroma
    return out[..., 0]


def _neighbours(a, y, x, r=2):
    block = a[y - r:y + r + 1, x - r:x + r + 1].copy()
    block[r, r] = np.nan
    return block[np.isfinite(block)]


# ------------------------------------------------------------------------- numpy: what it keeps

def test_an_isolated_firefly_is_clamped_into_its_neighbourhood():
    inputs, light = _flat()
    light[16, 16] = 50.0  # the noise's mean is 1
    light[8, 8], light[8, 9] = 40.0, 30.0  # two side by side: the brightest neighbour is left out
    out = _clamped(inputs, light)
    for y, x in ((16, 16), (8, 8), (8, 9)):
        near = _neighbours(light, y, x)
        near = near[near < 10]  # the noise around it, without the other firefly
        # within its neighbours' spread (mean 1, sd 0.3): above their mean, far below 30
        assert near.mean() < out[y, x] < near.mean() + 6 * near.std() < 3.0, (y, x, out[y, x])
    # the noise itself is barely touched: 4 sigmas of 24 neighbours lie far in its tail
    rest = np.ones_like(light, bool)
    rest[6:11, 6:12] = rest[15:18, 15:18] = False
    assert np.mean(out[rest] != light[rest]) < 0.01
    assert np.abs(out - light)[rest].sum() < 5e-3 * light[rest].sum()


def test_after_the_filter_the_firefly_is_gone_and_without_the_clamp_it_is_not():
    inputs, light = _flat(seed=1)
    inputs["color"][16, 16] *= 50.0
    ids = [GLOSSY]
    clean = denoise(**inputs, denoised_ids=ids) @ LUMA / 0.5  # illumination again
    kept = denoise(**inputs, denoised_ids=ids, outlier_sigmas=None) @ LUMA / 0.5
    assert kept[16, 16] > 5.0  # the luminance edge-stop shuts its neighbours out: a dot survives
    assert clean[16, 16] < 1.5 and np.abs(clean[12:21, 12:21] - 1.0).max() < 0.5


def test_a_highlight_wider_than_a_pixel_is_kept():
    inputs, light = _flat(seed=2)
    light[10:15, 10:15] *= 10.0  # a 5x5 highlight on the noise
    assert np.array_equal(_clamped(inputs, light)[10:15, 10:15], light[10:15, 10:15])


def test_a_one_pixel_line_and_a_smooth_peak_are_kept():
    """The bounds OUTLIER_SIGMAS = 4 keeps (frame/passes/denoise.py): on a clean plane, a bright line
    one pixel wide (its pixels have 4 bright neighbours among 24, one left out) and a smooth peak
    (every neighbour a little dimmer) stay exactly as they are."""
    inputs, light = _flat(noise=0.0)
    line = light.copy()
    line[12, :] = 10.0
    line[:, 20] = 10.0
    assert np.array_equal(_clamped(inputs, line), line)
    yy, xx = np.mgrid[:N, :N]
    peak = 1.0 + 4.0 * np.exp(-((yy - 16) ** 2 + (xx - 16) ** 2) / (2 * 1.5 ** 2))
    assert np.array_equal(_clamped(inputs, peak), peak)
    # ... while one bright pixel on the same clean plane is brought down to it
    dot = light.copy()
    dot[5, 5] = 10.0
    assert _clamped(inputs, dot)[5, 5] == pytest.approx(1.0)


def test_the_guides_keep_a_pixel_of_another_surface():
    """A bright pixel whose neighbours lie on another surface (a thin pole seen end on: nearer, facing
    sideways) or show another effect says nothing about noise: it is kept. (Depth alone would not
    tell: a one-pixel step reads as the centre's slope, the à-trous filter's own edge-stop alike.)"""
    inputs, light = _flat(seed=3)
    light[16, 16] = light[8, 24] = 50.0
    inputs["depth"][16, 16] = 0.5
    inputs["normal"][16, 16] = (1.0, 0.0, 0.0)
    inputs["effect"][8, 24] = EFFECTS["shadows"].id
    out = _clamped(inputs, light)
    assert out[16, 16] == light[16, 16] and out[8, 24] == light[8, 24]


# ----------------------------------------------------------------------------------- the GPU

def _raw(tex, dtype=np.float32, comps=4):
    w, h = tex.size[0], tex.size[1]
    return np.frombuffer(tex.read(), dtype).reshape(tex.layers, h, w, comps).copy()


def _lit_plane():
    """A wall seen head-on, lit by a rect light above it: `shadows` pixels, noisy at one sample."""
    from conftest import quad

    from rayvr.scene.loader import Light, Material, from_arrays

    v, f = quad((0.0, 0.0, -2.0), (3.0, 0.0, 0.0), (0.0, 2.0, 0.0))
    light = Light("rect", (1.0, 1.0, 1.0), 2.0, position=(0.0, 2.5, -1.0), u=(2.0, 0.0, 0.0), v=(0.0, 0.0, 1.0))
    return from_arrays(v, f, triangle_material=np.zeros(len(f), np.int64),
                       materials=[Material("wall", (0.8, 0.8, 0.8, 1.0))], lights=[light], ambient_lights=False)


def test_gpu_clamps_an_injected_firefly_as_numpy_does_and_keeps_a_highlight(gl):
    """A rendered frame's accumulated colour with a firefly (40x) and a 6x6 highlight (6x) written
    in, denoised again on the GPU: equal to the numpy twin; the firefly comes out near its
    surroundings, far below the unclamped filter's; the highlight as the unclamped filter has it."""
    cfg = parse_config({"default": "shadows", "params": {"shadows": {"area_samples": 1}}}, "<wall>")
    rig = StereoRig(Pose.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0)), ipd=0.0, fov_y=60.0, size=(48, 36))
    with Renderer(_lit_plane(), cfg, gl=gl, settings=RenderSettings(denoise=True, denoise_iterations=2)) as r:
        r.render(rig, spp=1)
        fc = r._last
        accum_tex = r.resource("hdr_accum")
        accum = _raw(accum_tex)
        fy, fx, hy, hx = 18, 16, slice(12, 18), slice(30, 36)
        accum[:, fy, fx, :3] *= 40.0
        accum[:, hy, hx, :3] *= 6.0
        accum_tex.write(accum.tobytes())
        denoise_pass = next(p for p in r.graph.compile(fc.plan).passes if p.name == "denoise")
        denoise_pass.execute(fc)
        gpu = _raw(r.resource("hdr_denoised"))[..., :3]
        gb = fc.gbuffer
        albedo = _raw(gb.textures["albedo"], np.float16)[..., :3].astype(np.float32)
        normal = _raw(gb.textures["normal"], np.float16)[..., :3].astype(np.float32)
        depth = _raw(gb.textures["position"])[..., 3]
        effect = _raw(gb.textures["material"], np.uint32, 2)[..., 1]
        moments = _raw(r.resource("accum_moments"))
    ids = [EFFECTS["shadows"].id]
    assert (effect[0] == ids[0]).all()  # the wall fills the view
    args = (accum[0, ..., :3], accum[0, ..., 3], moments[0, ..., :2], albedo[0], normal[0], depth[0], effect[0], ids)
    ref = denoise(*args, iterations=2)
    unclamped = denoise(*args, iterations=2, outlier_sigmas=None)
    err = np.abs(gpu[0] - ref) / np.maximum(np.abs(ref), 0.05)
    assert np.quantile(err, 0.999) < 2e-3 and err.max() < 2e-2, (np.quantile(err, 0.999), err.max())
    lum, lum_unclamped = gpu[0] @ LUMA, unclamped @ LUMA
    around = np.median(_neighbours(lum, fy, fx, r=3))
    assert lum[fy, fx] < 1.5 * around < 0.2 * lum_unclamped[fy, fx], (lum[fy, fx], around, lum_unclamped[fy, fx])
    inner = (slice(13, 17), slice(31, 35))
    assert np.allclose(lum[inner], lum_unclamped[inner], rtol=1e-3)


# ------------------------------------------------------------------------------- the capture

def _isolated_bright(png, effect) -> int:
    """Pixels of the denoised effects 1.25x brighter than their brightest 3x3 neighbour and by at
    least 0.02 (linear display luminance): the fireflies one sees."""
    x = np.asarray(Image.open(png))[..., :3].astype(np.float64) / 255.0
    lum = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4) @ LUMA
    h, w = lum.shape
    p = np.pad(lum, 1, mode="edge")
    top = np.max([p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dx or dy], 0)
    listed = np.isin(np.load(effect), [EFFECTS[e].id for e in ("shadows", "glossy")])
    return int((listed & (lum > 1.25 * top) & (lum - top > 0.02)).sum())


def test_capture_denoises_by_default_into_a_frame_without_fireflies(tmp_path):
    """`rayvr capture` with no flags but a small size: the built-in room denoised (the summary
    says so) with no isolated bright pixel on its sampled surfaces, in both eyes; --no-denoise
    gives the raw frame, fireflies and all."""
    from conftest import run_rayvr

    for name, extra in (("default", ()), ("raw", ("--no-denoise",))):
        run = run_rayvr("capture", "--size", "160x120", "--aux", "effect", *extra, "--out", tmp_path / name, "-q")
        assert run.returncode == 0, run.stderr
    assert json.loads((tmp_path / "default" / "frame_timings.json").read_text())["denoise"] == ["glossy", "shadows"]
    assert json.loads((tmp_path / "raw" / "frame_timings.json").read_text())["denoise"] == []
    for eye in ("left", "right"):
        counts = {name: _isolated_bright(tmp_path / name / f"frame_{eye}.png", tmp_path / name / f"frame_{eye}_effect.npy")
                  for name in ("default", "raw")}
        assert counts["raw"] >= 10 and counts["default"] == 0, (eye, counts)


def test_the_capture_default_yields_to_the_flags_the_config_and_a_budget_grid():
    """CAPTURE_DEFAULTS lie under everything a user says: --no-denoise, the config's [render]
    denoise = false; a budget grid may choose the denoiser (its base denoises where it does not)."""
    from rayvr.cli import build_parser
    from rayvr.commands.args import CAPTURE_DEFAULTS, budget_grid, render_values, with_capture_defaults

    def values(*argv, render=None):
        args = build_parser().parse_args(["capture", *argv])
        given = render_values(args, "capture", parse_config({"render": render or {}}, "<cfg>"))
        return args, given, with_capture_defaults(given)

    assert values()[2]["denoise"] is True
    assert values("--no-denoise")[2]["denoise"] is False
    assert values(render={"denoise": False})[2]["denoise"] is False
    assert values("--denoise", render={"denoise": False})[2]["denoise"] is True
    args, given, _ = values("--budget-ms", "5", "--frame-knobs", "denoise=off,on")
    assert {k.denoise for k in budget_grid(args, given, ("denoise",), defaults=CAPTURE_DEFAULTS)} == {False, True}
    args, given, _ = values("--budget-ms", "5", "--frame-knobs", "stereo=dual,reuse")
    assert {k.denoise for k in budget_grid(args, given, ("stereo",), defaults=CAPTURE_DEFAULTS)} == {True}
