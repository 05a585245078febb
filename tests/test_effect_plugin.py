"""An effect registered from outside rayvr (no file under rayvr/ edited): its parameters are
validated from its declaration, reach the GPU (a float), and its own pass renders its pixels.
Also: the compiled graph prunes what a scene does not need, as `rayvr info --graph` prints it."""
from __future__ import annotations

import re
from pathlib import Path

import moderngl
import numpy as np
import pytest

from conftest import run_rayvr
from rayvr.gl import shaders
from rayvr.frame.cameras.rig import StereoRig
from rayvr.frame.effects import Effect, Param, register, traced_effects, unregister
from rayvr.frame.graph import FramePlan, Pass, compose, read
from rayvr.gl.gpu_layout import IMAGE
from rayvr.scene.materials import ConfigError, parse_config
from rayvr.frame.passes.classify import bind_lists
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import load

HERE = Path(__file__).resolve().parent / "toy_effect"


class FlatFillPass(Pass):
    name = "flat_fill"

    def __init__(self, effect):
        self.effect = effect

    def why(self, plan: FramePlan):
        return "effect flat" if plan.view == "color" and "flat" in plan.effects else None

    def io(self, plan: FramePlan):
        return [read("gbuffer"), read("rt_lists"), read("rt_list_args"), compose("hdr")]

    def setup(self, gl, plan: FramePlan):
        self.slot = [e.name for e in traced_effects()].index("flat")
        self.program = shaders.compute(gl.ctx, "flat.comp", {"RT_SLOT": self.slot, **self.effect.param_defines()},
                                       root=HERE)

    def execute(self, fc):
        bind_lists(fc)
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()
        fc.resource("hdr").bind_to_image(IMAGE["hdr"], read=False, write=True)
        self.program["rt_capacity"].value = fc.sizing.pixels
        self.effect.frame_uniforms(self.program, [(a.rule, a.params) for a in fc.gpu_scene.assignments
                                                  if a.effect == self.effect.name])
        self.program.run_indirect(fc.resource("rt_list_args"), offset=16 * self.slot)
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self):
        self.program.release()


class Flat(Effect):
    name = "flat"
    doc = "its pixels glow at `glow` x `gain` x their base colour (a test plugin)"
    params = {"glow": Param(float, 2.5, 0.0, 100.0, "radiance per unit of base colour"),
              "gain": Param(float, 1.0, 0.0, 10.0, "one factor for the frame: the largest its materials ask for",
                            scope="frame", reduce="max")}
    traced = True

    def passes(self):
        return [FlatFillPass(self)]


@pytest.fixture
def flat():
    effect = register(Flat())
    try:
        yield effect
    finally:
        unregister("flat")


def test_a_plugin_effect_renders_its_pixels_with_its_float_parameter(gl, flat):
    scene = load()
    rig = StereoRig.for_scene(scene, size=(48, 36))
    settings = RenderSettings(ambient=(0.0, 0.0, 0.0))
    cfg = parse_config({"materials": {"mirror*": {"effect": "flat", "glow": 3.25}}}, "<plugin test>")
    with Renderer(scene, cfg, gl=gl, settings=settings) as r:
        assert "flat_fill" in r.compiled().pass_names and "bvh" not in r.compiled().pass_names
        frame = r.render(rig, aux=("hdr", "albedo", "effect"))
        counts = r.pixel_counts()
    with Renderer(scene, None, gl=gl, settings=settings) as r:
        plain = r.render(rig, aux=("hdr",))
    ids = np.stack([frame.left.aux["effect"], frame.right.aux["effect"]])
    mine = ids == flat.id
    assert counts["flat"] == mine.sum() > 20  # the classify pass listed exactly its pixels
    hdr = np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]])
    albedo = np.stack([frame.left.aux["albedo"], frame.right.aux["albedo"]])
    assert np.allclose(hdr[mine], 3.25 * albedo[mine], rtol=2e-3, atol=1e-3)  # float16 targets
    base = np.stack([plain.left.aux["hdr"], plain.right.aux["hdr"]])
    assert np.array_equal(hdr[~mine], base[~mine])  # nothing else changed
    assert not np.allclose(hdr[mine], base[mine])


def test_a_plugin_effect_validates_its_parameters(flat):
    with pytest.raises(ConfigError, match=r"glow.*outside the allowed range \[0.0, 100.0\]"):
        parse_config({"materials": {"m": {"effect": "flat", "glow": 500.0}}}, "<t>")
    with pytest.raises(ConfigError, match="glow: expected float, got str"):
        parse_config({"materials": {"m": {"effect": "flat", "glow": "bright"}}}, "<t>")
    with pytest.raises(ConfigError, match="finite"):
        parse_config({"materials": {"m": {"effect": "flat", "glow": float("nan")}}}, "<t>")
    assert parse_config({"default": "flat"}, "<t>").effect_params("flat") == {"glow": 2.5, "gain": 1.0}


def test_a_frame_parameter_is_one_uniform_of_the_largest_value_and_takes_no_material_word(gl, flat):
    """`gain` is scope="frame", reduce="max": it has no word in the material block (no PARAM_GAIN),
    and every flat pixel of a frame whose materials ask 2 and 1 is lit with gain 2."""
    assert flat.param_slots() == {"glow": 0} and "PARAM_GAIN" not in flat.param_defines()
    scene = load()
    rig = StereoRig.for_scene(scene, size=(48, 36))
    cfg = parse_config({"materials": {"mirror*": {"effect": "flat", "glow": 3.0, "gain": 2.0},
                                      "floor": {"effect": "flat", "glow": 3.0, "gain": 1.0}}}, "<plugin test>")
    with Renderer(scene, cfg, gl=gl, settings=RenderSettings(ambient=(0.0, 0.0, 0.0))) as r:
        users = [(a.rule, a.params) for a in r.assignments if a.effect == "flat"]
        assert {rule for rule, _ in users} == {"materials.mirror*", "materials.floor"}
        assert flat.frame_values(users) == {"gain": 2.0} and flat.frame_values([]) == {"gain": 1.0}
        frame = r.render(rig, aux=("hdr", "albedo", "effect"))
    mine = np.stack([frame.left.aux["effect"], frame.right.aux["effect"]]) == flat.id
    hdr = np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]])
    albedo = np.stack([frame.left.aux["albedo"], frame.right.aux["albedo"]])
    assert mine.sum() > 40 and np.allclose(hdr[mine], 6.0 * albedo[mine], rtol=2e-3, atol=1e-3)


def test_a_frame_parameter_its_materials_must_agree_on_is_refused_naming_them():
    class Tiled(Effect):
        name = "tiled"
        params = {"tile": Param(int, 16, 1, 64, "one tile size for the frame", scope="frame"),
                  "glow": Param(float, 1.0, 0.0, 10.0)}

    register(Tiled())
    try:
        assert Tiled.params["tile"].reduce == "agree"  # the default reducer of a frame parameter
        cfg = parse_config({"default": "tiled", "materials": {"wall": {"effect": "tiled", "tile": 8, "glow": 2.0}}},
                           "<agree test>")
        with pytest.raises(ConfigError, match=r"^<agree test>: tiled.tile is one value per frame for every material "
                                              r"of tiled, and they differ \(floor 16, wall 8\): give them one value$"):
            cfg.assign(["floor", "wall"])
        same = parse_config({"default": "tiled", "params": {"tiled": {"tile": 8}},
                             "materials": {"wall": {"effect": "tiled", "glow": 2.0}}}, "<agree test>")
        assert [a.params["glow"] for a in same.assign(["floor", "wall"])] == [1.0, 2.0]  # material values differ freely
    finally:
        unregister("tiled")
    with pytest.raises(TypeError, match="takes no reducer"):
        Param(float, 1.0, reduce="max")
    with pytest.raises(TypeError, match="reducer is one of max, min, agree"):
        Param(float, 1.0, scope="frame", reduce="mean")


def test_registry_refuses_clashes(flat):
    from rayvr.frame.effects import EffectError

    with pytest.raises(EffectError, match="registered already"):
        register(Flat())
    with pytest.raises(EffectError, match="identifier"):
        register(type("Bad", (Effect,), {"name": "no spaces please"})())


def test_effect_ids_come_from_the_registry_in_the_ladders_order(flat):
    """No effect names its ID: rayvr's rungs take 0.. in the order rayvr/frame/effects/__init__.py
    registers them (the ladder's, which the G-buffer's effect channel and captures' aux "effect"
    images keep), and a plugin the next free one."""
    from rayvr.frame import effects
    from rayvr.frame.effects import EFFECTS

    ladder = ["raster", "shadows", "ssr", "reflections", "glossy", "path", "photon"]
    assert [EFFECTS[n].id for n in ladder] == list(range(len(ladder)))
    assert EFFECTS["flat"].id == len(ladder)
    sources = Path(effects.__file__).parent
    hand = [p.name for p in sources.rglob("*.py") if re.search(r"(?m)^    id = \d", p.read_text())]
    assert hand == []


def _graph(*args):
    run = run_rayvr("info", *args)
    assert run.returncode == 0, run.stderr
    return run.stdout


def test_graph_prunes_what_the_scene_does_not_need():
    text = _graph("--materials", "raster.toml", "--graph", "--size", "64x48")
    passes = re.findall(r"(?m)^\s+\d+\. (\S+)", text)
    assert passes == ["visibility", "gbuffer", "shade", "tonemap"], passes  # all raster: no BVH, no lists
    assert "bvh" not in text and "rt_lists" not in text
    room = str(Path(__file__).resolve().parents[1] / "rayvr" / "assets" / "default_room.toml")
    traced = _graph("--materials", room, "--graph", "--size", "64x48")
    for name in ("bvh", "classify", "rt_shadows", "rt_reflections", "rt_glossy"):
        assert f" {name} " in traced, name
    assert "mirror" in traced  # why rt_reflections runs: the materials that use it
    assert _graph("--graph", "--size", "64x48") == traced  # the room without --materials: its own config, as capture
    rays = re.findall(r"(?m)^\s+\d+\. (\S+)", _graph("--materials", "raster.toml", "--graph", "--primary", "rays",
                                                        "--size", "64x48"))
    assert rays == ["bvh", "primary_rays", "gbuffer", "shade", "tonemap"], rays
    dot = _graph("--materials", room, "--graph", "dot")  # a capture's graph: denoised before the tonemap
    assert dot.startswith("digraph") and '"res:hdr_denoised" -> "tonemap"' in dot and "compose" in dot
    raw = _graph("--materials", room, "--graph", "dot", "--no-denoise")
    assert '"res:hdr" -> "tonemap"' in raw and "denoise" not in raw
