"""Adaptive area-light shadows (glsl/rt/wave_trace.comp adaptive_run, RenderSettings.shadow_probes):
K of a rect light's N shadow rays first, the rest only where those K disagree. Judged against every
ray traced (shadow_probes 0) on a square blocker under a square light, whose umbra, penumbra and
fully lit floor are known from geometry: exact where the light is wholly hidden or wholly seen,
its bias in the penumbra bounded by the full count's own noise."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays
from rayvr.scene.materials import parse_config

# The light: a square of half-size L at height H; the blocker: a square of half-size B at height
# H / 2, both centred over the origin. From a floor point p the blocker projects onto the light's
# plane as a square of half-size 2B centred at -p (xz): its overlap with the light is the hidden part.
L, B, H = 0.6, 0.5, 2.0


def scene():
    v, f, part = merge(quad((0, 0, 0), (4, 0, 0), (0, 0, -4)), quad((0, H / 2, 0), (B, 0, 0), (0, 0, -B)))
    return from_arrays(v, f, triangle_material=part, materials=[Material("floor"), Material("blocker")],
                       lights=[Light("rect", intensity=4, position=(0, H, 0), u=(L, 0, 0), v=(0, 0, L))])


def hidden_fraction(x, z):
    """The share of the light the blocker hides from floor point (x, z): the overlap of the squares."""
    def overlap(c):
        return np.clip(np.minimum(-c + 2 * B, L) - np.maximum(-c - 2 * B, -L), 0.0, None)
    return overlap(x) * overlap(z) / (2 * L) ** 2


def render(gl, probes, seed, samples=16):
    cfg = parse_config({"default": "shadows", "params": {"shadows": {"area_samples": samples}}}, "t")
    settings = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0), shadow_probes=probes, seed=seed)
    rig = StereoRig(Pose.look_at((0, 4.5, 2.5), (0, 0, 0)), ipd=0.1, fov_y=50, size=(64, 48))
    with Renderer(scene(), cfg, gl=gl, settings=settings) as r:
        frame = r.render(rig, aux=("hdr", "material", "position"))
    hdr = np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]]).mean(-1)
    mat = np.stack([frame.left.aux["material"], frame.right.aux["material"]])
    pos = np.stack([frame.left.aux["position"], frame.right.aux["position"]])
    return hdr, mat, pos


@pytest.fixture(scope="module")
def floor(gl):
    """Every ray traced at seeds 1 and 2, and the floor's regions from geometry."""
    full1, mat, pos = render(gl, 0, 1)
    full2, _, _ = render(gl, 0, 2)
    on_floor = mat == 0
    hidden = hidden_fraction(pos[..., 0], pos[..., 2])
    margin = 0.02  # half a lattice cell of the light at 16 points, in hidden share
    regions = {"umbra": on_floor & (hidden >= 1 - 1e-9), "lit": on_floor & (hidden <= 0.0),
               "penumbra": on_floor & (hidden > margin) & (hidden < 1 - margin)}
    assert all(m.sum() > 50 for m in regions.values()), {k: int(m.sum()) for k, m in regions.items()}
    return full1, full2, regions


@pytest.mark.parametrize("probes", [2, 4])
def test_a_wholly_hidden_or_wholly_seen_light_is_exact(gl, floor, probes):
    full1, _, regions = floor
    got, _, _ = render(gl, probes, 1)
    assert np.all(got[regions["umbra"]] == 0.0)
    assert full1[regions["lit"]].min() > 1e-3
    assert np.allclose(got[regions["lit"]], full1[regions["lit"]], rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("samples", [8, 16])
def test_the_penumbra_is_closer_to_every_ray_than_the_probes_alone(gl, floor, samples):
    """In the penumbra the adaptive estimate (4 probes of `samples`, seed 1) costs at least the
    probes' 4 rays; against every ray of 16 traced at another seed (2) it must beat tracing just 4
    rays a light (seed 1), and its mean over the penumbra must stay within 2 % of every ray's
    (seed 1): where the probes agree wrongly the errors fall both ways."""
    _, full2, regions = floor
    pen = regions["penumbra"]
    got, _, _ = render(gl, 4, 1, samples)
    four, _, _ = render(gl, 0, 1, 4)
    full, _, _ = render(gl, 0, 1, samples)
    err, err_four = (np.abs(x - full2)[pen].mean() for x in (got, four))
    assert err < 0.9 * err_four, (err, err_four)
    bias = abs(got[pen].mean() - full[pen].mean()) / full[pen].mean()
    assert bias < 0.02, bias


def test_probes_at_least_the_rays_trace_every_ray(gl, floor):
    """A light with no more rays than probes is traced whole: the same image as shadow_probes 0."""
    got, _, _ = render(gl, 16, 1)
    assert np.array_equal(got, floor[0])


def test_the_gpu_counts_the_rays_the_probes_save(gl):
    """count_rays on the blocker scene: with every ray traced a pixel casts its 16 shadow rays (a
    few fewer where the light is behind the surface); with 4 probes the lit floor and the umbra
    take 4: fewer rays, and at least 4 a pixel."""
    from rayvr.frame.passes.trace_effect import count_rays

    rig = StereoRig(Pose.look_at((0, 4.5, 2.5), (0, 0, 0)), ipd=0.1, fov_y=50, size=(64, 48))
    cfg = parse_config({"default": "shadows", "params": {"shadows": {"area_samples": 16}}}, "t")
    counted = {}
    for probes in (0, 4):
        settings = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0), shadow_probes=probes, seed=1)
        with Renderer(scene(), cfg, gl=gl, settings=settings) as r:
            counted[probes] = count_rays(r, rig)["shadows"]
    assert counted[0]["pixels"] == counted[4]["pixels"] > 0
    assert counted[0]["closest"] == counted[4]["closest"] == 0  # shadows trace no reflection rays
    assert counted[0]["shadow"] <= 16 * counted[0]["pixels"]
    assert counted[0]["shadow"] > 15 * counted[0]["pixels"]  # the floor's far side faces away: few skip
    assert 4 * counted[4]["pixels"] <= counted[4]["shadow"] < 0.6 * counted[0]["shadow"]


def test_where_no_run_outnumbers_its_probes_the_plain_kernel_traces_the_same_rays(gl, monkeypatch):
    """With as many probes as a light has points (16), the adaptive loop traces every ray; the pass
    then takes the plain loop (WaveShape.adaptive False), and forcing the adaptive one gives the same
    image (up to the order of the sums). shadow_probes 0 also takes the plain loop: the same frame."""
    from rayvr.frame.passes import trace_effect

    plain, _, _ = render(gl, 16, 1)
    every, _, _ = render(gl, 0, 1)
    np.testing.assert_array_equal(plain, every)
    monkeypatch.setattr(trace_effect.WaveShape, "adaptive", lambda self, probes: True)
    forced, _, _ = render(gl, 16, 1)
    np.testing.assert_allclose(forced, plain, rtol=1e-3, atol=1e-4)
    assert plain.max() > 0.1  # a lit floor, not an empty comparison


def test_only_a_rect_lights_run_longer_than_the_probes_is_adaptive():
    """WaveShape.adaptive: a rect light whose points outnumber the probes; not without a rect light,
    with probes 0, or with probes at least the slots an event holds."""
    from types import SimpleNamespace

    from rayvr.frame.effect_registry import EFFECTS
    from rayvr.frame.passes.trace_effect import WaveShape

    def shape(lights, samples):
        s = SimpleNamespace(assignments=[SimpleNamespace(effect="shadows", rule="*", params={"area_samples": samples})],
                            scene=SimpleNamespace(lights=lights), light_picks=0, wave_buffer_bytes=None,
                            max_ssbo_bytes=None, pixels=64)
        return WaveShape(EFFECTS["shadows"], s)
    rect, point = Light("rect", position=(0, 1, 0), u=(1, 0, 0), v=(0, 0, 1)), Light("point", position=(0, 1, 0))
    assert shape([rect], 16).adaptive(4)
    assert not shape([rect], 16).adaptive(0)
    assert not shape([rect], 4).adaptive(4)
    assert not shape([point, point], 16).adaptive(4)
