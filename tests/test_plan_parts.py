"""The frame plan from its owners' parts (rayvr/options.py plan_part): each owner of plan options
adds its FramePlan fields or refuses in words of the renderer, a plan option without a part reaches
its plan field as given, and the command line turns a refusal into its flags. A plugin's plan
option and part touch only the plugin's own code (here: this file)."""
from __future__ import annotations

import pytest

from rayvr import Renderer
from rayvr.options import (Option, PlanAsk, PlanRefusal, declare, flag_words, plan_fields, plan_part, remove,
                           remove_plan_part)
from rayvr.renderer import RenderSettings


@pytest.fixture
def toy_plan_option():
    """A plugin's two plan options: `toy_mode` with a policy (a part that reads the primary part's
    field and may refuse), `toy_level` without one (its value as given)."""
    declare(Option("toy_mode", str, "a", "the toy pass's mode", choices=("a", "b", "off"), scope="plan",
                   plan_field="toy_mode", commands=("capture",)), owner="tests.toy")
    declare(Option("toy_level", int, 1, "the toy pass's level", bounds=(0, 9), scope="plan", plan_field="toy_level"),
            owner="tests.toy")

    @plan_part("toy", after=("primary",))
    def toy_part(ask, plan):
        if ask.settings.toy_mode == "b" and plan["primary"] != "rays":
            raise PlanRefusal("toy mode b reads the ray-cast G-buffer", "use", ("primary", "rays"))
        plan["toy_mode"] = ask.settings.toy_mode
    yield
    remove_plan_part("toy")
    remove("toy_mode")
    remove("toy_level")


def test_a_plugin_plan_option_reaches_the_plan_through_its_own_part(gl, toy_plan_option):
    with Renderer(None, gl=gl) as r:
        assert r.plan().part("toy_mode") == "a" and r.plan().part("toy_level") == 1
        r.settings = RenderSettings(toy_mode="b", primary="rays", toy_level=7)
        plan = r.plan()
        assert plan.part("toy_mode") == "b" and plan.part("toy_level") == 7 and plan.primary == "rays"
        r.settings = RenderSettings(toy_mode="a", primary="rays", toy_level=7)
        assert r.plan() != plan  # the plugin's fields key the compiled graphs too
        r.settings = RenderSettings(toy_mode="b")
        with pytest.raises(PlanRefusal) as refused:
            r.plan()
    assert str(refused.value) == "toy mode b reads the ray-cast G-buffer: use primary='rays'"
    assert refused.value.in_flags() == "toy mode b reads the ray-cast G-buffer: use --primary rays"


def test_the_command_line_says_a_refusal_in_flags(capsys):
    from rayvr.cli import main

    assert main(["capture", "--msaa", "4", "--stereo", "warp", "--size", "16x12", "--out", "/nonexistent/x"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("reprojects one sample per pixel: it cannot take 4 sub-rays a sample: use --stereo dual"), err
    assert "stereo='dual'" not in err


def test_rayvr_refusals_name_options_not_flags(gl):
    with Renderer(None, gl=gl, settings=RenderSettings(primary="rays", tile_culling=False, tile_lists=64)) as r:
        with pytest.raises(PlanRefusal, match=r"entry lists: leave out tile_culling=False$") as refused:
            r.plan()
    assert refused.value.in_flags().endswith("leave out --no-tile-culling")


def test_parts_run_after_those_they_name_and_a_loop_is_refused(toy_plan_option):
    seen = []

    @plan_part("toy_late", after=("toy_early",))
    def late(ask, plan):
        seen.append(("late", plan.get("early")))

    @plan_part("toy_early")
    def early(ask, plan):
        plan["early"] = 1
        seen.append(("early", None))
    try:
        fields = plan_fields(PlanAsk(RenderSettings(), _Camera()), {"effects": frozenset()})
        assert seen == [("early", None), ("late", 1)] and fields["toy_level"] == 1
        plan_part("toy_early", after=("toy_late",))(early)
        with pytest.raises(ValueError, match="in a loop"):
            plan_fields(PlanAsk(RenderSettings(), _Camera()), {})
    finally:
        remove_plan_part("toy_late")
        remove_plan_part("toy_early")


class _Camera:
    name, rasterizable, channels, sparse, lens_parameter = "pinhole", True, 1, False, ""


def test_flag_words():
    assert flag_words("msaa", 4) == "--msaa 4"
    assert flag_words("tile_culling", False) == "--no-tile-culling" and flag_words("temporal", True) == "--temporal"
    assert flag_words("dof_focus", 3.0) == "--focus-distance 3.0"  # the option's own flag
    assert flag_words("traversal", ("bvh2", "bvh2", "cwbvh")) == "--traversal bvh2,bvh2,cwbvh"


def test_eyes_is_the_plans_count_of_views_and_layers_its_old_name(gl):
    with Renderer(None, gl=gl) as r:
        assert r.plan(eyes=1).eyes == 1 and r.plan().eyes == 2
        with pytest.warns(DeprecationWarning, match="use eyes"):
            plan = r.plan(layers=1)
    assert plan.eyes == 1 and plan.layers == 1


def test_subsamples_are_a_samples_sub_rays_and_samples_their_old_name(gl):
    with Renderer(None, gl=gl, settings=RenderSettings(msaa=4)) as r:
        plan = r.plan()
    assert plan.subsamples == 4 and plan.samples == 4 and plan.sampled
