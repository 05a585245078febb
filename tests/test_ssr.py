"""The `ssr` effect: mirror rays through the screen-space quadtree, BVH fallback, checked against
BVH `reflections` on the same pixels (an independent tracer of the same rays)."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.frame.cameras.rig import StereoRig
from rayvr.scene.materials import parse_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import load

DARK = RenderSettings(ambient=(0.0, 0.0, 0.0))
MIRRORS = ("floor", "mirror*")


def render(gl, effect, rig, **params):
    cfg = parse_config({"materials": {m: {"effect": effect, **params} for m in MIRRORS}}, "<ssr test>")
    with Renderer(load(), cfg, gl=gl, settings=DARK) as r:
        frame = r.render(rig, aux=("hdr", "effect"))
        passes = r.compiled().pass_names
    return frame, passes


@pytest.fixture(scope="module")
def rig():
    return StereoRig.for_scene(load(), size=(96, 72))


@pytest.fixture(scope="module")
def bvh(gl, rig):
    return render(gl, "reflections", rig)[0]


def test_graph_builds_the_quadtree_only_for_ssr(gl, rig, bvh):
    _, passes = render(gl, "ssr", rig)
    assert passes.index("gbuffer") < passes.index("quadtree") < passes.index("rt_ssr") < passes.index("tonemap")
    _, plain = render(gl, "reflections", rig)
    assert "quadtree" not in plain


@pytest.mark.parametrize("gammas", [{"gamma_norm": 1.0, "gamma_dist": 0.0}, {}], ids=["lossless", "default"])
def test_ssr_matches_bvh_reflections_where_the_screen_sees_the_reflection(gl, rig, bvh, gammas):
    frame, _ = render(gl, "ssr", rig, **gammas)
    for eye in ("left", "right"):
        mine = frame[eye].aux["effect"] == 2  # rayvr.frame.effects.ssr id
        assert mine.sum() > 500
        a, b = frame[eye].aux["hdr"], bvh[eye].aux["hdr"]
        assert np.array_equal(a[~mine], b[~mine])  # nothing else changes
        err = np.abs(a[mine] - b[mine]).mean(-1)
        # Screen-space hits differ from BVH ones where a reflected point is hidden in the single
        # layer yet within `thickness` of a surface, and by the tree's plane approximation:
        # measured 1.8 % of the mean radiance on these pixels; most pixels agree closely.
        assert err.mean() < 0.08 * b[mine].mean(), (err.mean(), b[mine].mean())
        assert np.median(err) < 0.01 * b[mine].mean()


def test_without_fallback_rays_the_screen_cannot_answer_see_the_background(gl, rig, bvh):
    with_bvh, _ = render(gl, "ssr", rig, fallback=1)
    alone, _ = render(gl, "ssr", rig, fallback=0)
    mine = with_bvh.left.aux["effect"] == 2
    ref = bvh.left.aux["hdr"][mine]
    err_bvh = np.abs(with_bvh.left.aux["hdr"][mine] - ref).mean()
    err_alone = np.abs(alone.left.aux["hdr"][mine] - ref).mean()
    assert err_alone > 1.1 * err_bvh, (err_alone, err_bvh)  # the fallback answers the off-screen rays
    changed = np.abs(alone.left.aux["hdr"][mine] - with_bvh.left.aux["hdr"][mine]).max(-1) > 1e-3
    assert 0.01 < changed.mean() < 0.9, changed.mean()  # some rays, not all, needed it


def test_ipd_zero_gives_identical_eyes(gl):
    rig = StereoRig.for_scene(load(), size=(48, 36), ipd=0.0)
    frame, _ = render(gl, "ssr", rig)
    assert np.array_equal(frame.left.aux["hdr"], frame.right.aux["hdr"])
    assert np.isfinite(frame.left.aux["hdr"]).all()


def test_quadtree_visits_view(gl, rig):
    """The debug view of node visits: every covered pixel's mirror ray tests at least one node (the
    exact count in red), background pixels are black; merged thresholds (an ssr material asking
    for them) test fewer nodes than the lossless tree."""
    scene = load()

    def visits(config):
        with Renderer(scene, parse_config(config, "<visits>"), gl=gl, settings=DARK) as r:
            frame = r.render(rig, view="quadtree_visits", aux=("triangle",))
            assert "quadtree" in r.compiled(r.plan(2, "quadtree_visits")).pass_names
        covered = frame.left.aux["triangle"] != 0xFFFFFFFF
        red = frame.left.color[..., 0].astype(int)
        assert (red[covered] >= 1).all() and (frame.left.color[~covered] == 0).all()
        return red[covered].mean()

    lossless = visits({})
    merged = visits({"materials": {"floor": {"effect": "ssr", "gamma_norm": 0.9, "gamma_dist": 0.1}}})
    assert merged < lossless, (merged, lossless)


def test_thickness_sends_rays_that_passed_behind_an_object_to_the_bvh(gl, rig, bvh):
    """With pure height-field semantics (thickness 1e30) a ray passing behind a foreground object
    'hits' it; the default thickness leaves such rays to the BVH fallback, which is exact."""
    mine = bvh.left.aux["effect"] == 3  # where `reflections` is, ssr will be
    ref = bvh.left.aux["hdr"][mine]
    errs = {}
    for thickness in (0.02, 1e30):
        frame, _ = render(gl, "ssr", rig, thickness=thickness)
        errs[thickness] = np.abs(frame.left.aux["hdr"][mine] - ref).mean()
    assert errs[0.02] < 0.7 * errs[1e30], errs


def render_with(gl, rig, settings, effect, **params):
    cfg = parse_config({"materials": {m: {"effect": effect, **params} for m in MIRRORS}}, "<ssr test>")
    with Renderer(load(), cfg, gl=gl, settings=settings) as r:
        return r.render(rig, aux=("hdr", "effect")), r.compiled().pass_names


@pytest.mark.parametrize("second", ["rays", "peel"])
def test_two_layers_with_either_second_layer(gl, rig, bvh, second):
    """layers = 2: the second_layer pass runs (before the quadtree) only then; with and without the
    fallback the image stays within 8 % of BVH reflections' mean radiance on the ssr pixels, no
    NaN, both ways to make the layer. (In the room two layers do not beat one: what lies behind
    the boxes' front faces is their own back faces, so rays inside them stay unanswered.)"""
    from dataclasses import replace
    settings = replace(DARK, second_layer=second)
    mine = bvh.left.aux["effect"] == 3
    ref = bvh.left.aux["hdr"][mine]
    err = {}
    for fallback in (0, 1):
        frame, passes = render_with(gl, rig, settings, "ssr", layers=2, fallback=fallback)
        assert passes.index("second_layer") < passes.index("quadtree")
        hdr = frame.left.aux["hdr"]
        assert np.isfinite(hdr).all() and np.isfinite(frame.right.aux["hdr"]).all()
        err[fallback] = np.abs(hdr[mine] - ref).mean()
    assert err[1] < 0.08 * ref.mean() and err[0] < 0.08 * ref.mean(), err
    _, passes = render_with(gl, rig, settings, "ssr", layers=1)
    assert "second_layer" not in passes


def test_glossy_rays_on_rough_materials(gl, rig):
    """samples > 0: GGX rays on materials rougher than MIRROR_ROUGHNESS (the floor, 0.25) traced
    in screen space with BVH fallback match BVH `glossy` with the same samples on those pixels
    (the same seeds: the same rays); mirrors keep one mirror ray; IPD 0 gives identical eyes."""
    ref, _ = render(gl, "glossy", rig, samples=4)
    mine_ref = ref.left.aux["effect"] == 4
    frame, _ = render(gl, "ssr", rig, samples=4, gamma_norm=1.0, gamma_dist=0.0)
    mine = frame.left.aux["effect"] == 2
    assert (mine == mine_ref).all() and mine.sum() > 500
    a, b = frame.left.aux["hdr"][mine], ref.left.aux["hdr"][mine]
    assert np.isfinite(a).all()
    assert np.abs(a - b).mean() < 0.08 * b.mean(), (np.abs(a - b).mean(), b.mean())
    mirror, _ = render(gl, "ssr", rig, samples=0)
    assert not np.array_equal(mirror.left.aux["hdr"][mine], a)   # the floor's rays changed
    zero = StereoRig.for_scene(load(), size=(48, 36), ipd=0.0)
    f0, _ = render(gl, "ssr", zero, samples=4)
    assert np.array_equal(f0.left.aux["hdr"], f0.right.aux["hdr"])


def test_the_quadtree_thresholds_are_frame_parameters_of_the_strictest_material():
    """gamma_norm and gamma_dist build the one quadtree of a frame: frame-scoped (no material
    words: ssr keeps its words for per-material values, mirror_roughness among them), reduced to the
    strictest any ssr material asks for; materials that disagree fill the same material table as
    materials that all ask for that strictest pair."""
    from rayvr.frame.effects import EFFECTS
    from rayvr.frame.effects.ssr import MIRROR_ROUGHNESS
    from rayvr.scene.gpu_scene import material_records
    from rayvr.frame.passes.quadtree import QuadtreePass

    ssr = EFFECTS["ssr"]
    assert "gamma_norm" not in ssr.param_slots() and "gamma_dist" not in ssr.param_slots()
    assert "mirror_roughness" in ssr.param_slots() and ssr.params["mirror_roughness"].default == MIRROR_ROUGHNESS
    scene = load()
    mixed = parse_config({"materials": {"floor": {"effect": "ssr", "gamma_norm": 0.9, "gamma_dist": 0.01},
                                        "mirror*": {"effect": "ssr", "gamma_norm": 0.99, "gamma_dist": 0.05}}}, "<t>")
    strict = parse_config({"materials": {m: {"effect": "ssr", "gamma_norm": 0.99, "gamma_dist": 0.01}
                                         for m in MIRRORS}}, "<t>")
    mixed_a, strict_a = (c.assign(scene.material_names()) for c in (mixed, strict))
    assert QuadtreePass().thresholds(mixed_a) == (0.99, 0.01) == QuadtreePass().thresholds(strict_a)
    layers = [0] * len(scene.materials)
    assert np.array_equal(material_records(scene, mixed_a, layers), material_records(scene, strict_a, layers))
