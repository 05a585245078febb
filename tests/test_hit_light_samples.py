"""Light samples where a reflection ray lands (`hit_area_samples`, glsl/rt/wave_shade.comp
path_vertex_begin): by default the pixel's area_samples spread over the rays it sends, at least one
a ray, instead of area_samples at every hit. The full count stays the reference: the same room
converges to the same image either way, and the waves are sized for what the hits take."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.frame.cameras.rig import StereoRig
from rayvr.frame.passes.trace_effect import WaveShape, hit_points
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import load
from rayvr.scene.materials import EFFECTS, parse_config


@pytest.mark.parametrize("effect, params, points", [
    ("glossy", {"samples": 4, "area_samples": 4}, 1),        # 4 rays share the pixel's 4 points
    ("glossy", {"samples": 4, "area_samples": 8}, 2),
    ("glossy", {"samples": 3, "area_samples": 8}, 3),        # rounded up: at least area_samples in all
    ("glossy", {"samples": 16, "area_samples": 4}, 1),       # at least one a ray
    ("glossy", {"samples": 4, "area_samples": 8, "hit_area_samples": 5}, 5),  # given: as given
    ("reflections", {"area_samples": 8}, 8),                 # one mirror ray keeps the pixel's count
    ("ssr", {"samples": 4, "area_samples": 8}, 8),           # ssr's mirror pixels send one ray
    ("path", {"samples": 4, "area_samples": 2}, 2),          # path lights every vertex with area_samples
])
def test_hit_points_follow_the_rays_a_pixel_sends(effect, params, points):
    full = {k: p.default for k, p in EFFECTS[effect].params.items() if p.scope == "material"}
    assert hit_points(EFFECTS[effect], {**full, **params}) == points


def room_shape(config):
    scene = load(None)
    cfg = parse_config(config, "t")
    with Renderer(scene, cfg) as r:
        plan = r.plan(2, "color")
        return {e: WaveShape(EFFECTS[e], r.sizing((8, 6), 2, plan)) for e in ("glossy", "reflections")}, scene


def test_the_hit_events_shadow_slots_are_sized_by_hit_points(gl):
    config = {"default": "shadows", "materials": {"floor": {"effect": "glossy", "samples": 4, "area_samples": 8},
                                                   "gold": {"effect": "glossy", "samples": 8, "area_samples": 8},
                                                   "mirror*": {"effect": "reflections", "area_samples": 8}}}
    shapes, scene = room_shape(config)
    rects = sum(light.kind == "rect" for light in scene.lights)
    others = len(scene.lights) - rects
    assert rects >= 1
    assert shapes["glossy"].hit_slots == 2 * rects + others  # the floor's 8 / 4 (the gold takes 1)
    assert shapes["reflections"].hit_slots == 8 * rects + others
    assert shapes["glossy"].slots == 8 * rects + others  # the pixel's own surface keeps area_samples


def room_image(gl, hit, seed, spp):
    """The built-in room's glossy floor and gold with `hit` points a light at their rays' hits,
    the mean of `spp` frames; and the glossy pixels."""
    cfg = parse_config({"default": "shadows",
                        "materials": {"floor": {"effect": "glossy", "samples": 4, "area_samples": 8,
                                                "hit_area_samples": hit},
                                      "gold": {"effect": "glossy", "samples": 4, "area_samples": 8,
                                               "hit_area_samples": hit}}}, "t")
    scene = load(None)
    rig = StereoRig.for_scene(scene, size=(40, 30))
    with Renderer(scene, cfg, gl=gl, settings=RenderSettings(seed=seed, shadow_probes=0)) as r:
        frame = r.render(rig, aux=("hdr", "effect"), spp=spp)
    hdr = np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]])
    glossy = np.stack([frame.left.aux["effect"], frame.right.aux["effect"]]) == EFFECTS["glossy"].id
    return hdr, glossy


def test_one_light_sample_a_ray_converges_to_the_full_count(gl):
    """Glossy pixels with one light sample per ray at its hit (the default 0 here: 8 points over
    4 rays = 2; and 1 given) against the full count (8 at every hit, 64 frames, another seed):
    their means over 16 frames lie closer to it than two renders of the cheap setting lie to each
    other (with a reference 4x converged, noise alone gives about 0.8 of that; a bias adds to it),
    and the glossy pixels' mean within 2 %."""
    ref, glossy = room_image(gl, 8, 100, 64)
    assert glossy.sum() > 100
    for hit in (0, 1):
        a, _ = room_image(gl, hit, 1, 16)
        b, _ = room_image(gl, hit, 2, 16)
        err = np.abs(a - ref)[glossy].mean()
        noise = np.abs(a - b)[glossy].mean()
        assert err < 0.95 * noise, (hit, err, noise)
        assert abs(a[glossy].mean() / ref[glossy].mean() - 1) < 0.02, hit
