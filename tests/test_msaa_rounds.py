"""MSAA rounds recorded without waiting for the GPU's round count (frame/passes/primary_rays.py
COUNT_POLL, the conftest `count_poll` fixture): the frame is bit-identical whether the count is
known after the first round ("wait") or never while recording ("never": every channel set records
msaa_slots rounds, those past the count dispatch nothing through the round gate), and whether empty slots are skipped or
shaded as background of weight 0 (FramePlan.skip_empty_slots); colour, depth and every aux channel."""
import numpy as np
import pytest

from rayvr import Renderer
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Distorted
from rayvr.frame.graph import FramePlan
from rayvr.scene.materials import parse_config
from rayvr.frame.passes import primary_rays
from rayvr.frame.passes.classify import pixel_counts
from rayvr.renderer import RenderSettings
from rayvr.scene.loader import load

POSE = Pose.look_at([0.3, 1.5, 1.0], [0.3, 2.5, -1])  # the default room's ceiling corner: 3 triangles at most in a pixel
AUX = ("hdr", "position", "normal", "albedo", "material", "triangle")


@pytest.fixture(scope="module")
def room():
    return load(None)


def frames(gl, room, count_poll, settings, variants, camera=None, materials=None):
    """One frame per (COUNT_POLL, skip_empty_slots) variant, each from a fresh Renderer (the select
    is compiled with the variant), with its rounds recorded and needed per channel set and the
    last round's sample weights."""
    rig = StereoRig(POSE, ipd=0.064, fov_y=60, size=(32, 24), near=1e-3, **({"camera": camera} if camera else {}))
    out = []
    for poll, skip in variants:
        count_poll(poll)
        with Renderer(room, materials, gl=gl, settings=settings, skip_empty_slots=skip) as r:
            frame = r.render(rig, aux=AUX)
            fc = r.record(rig)  # the same frame again, its rounds inspected
            r.gl.ctx.finish()
            rounds = [(c.ordinal + 1, c.needed()) for c in fc.channel_rounds]
            weight = np.frombuffer(r.resource("sample_weight").read(), np.float32)
            if "rt_list_args" in fc.resources:  # the traced effects' pixels in the last round
                weight = (weight, pixel_counts(fc.resource("rt_list_args")))
        out.append((frame, rounds, weight))
    return out


def assert_same(a, b):
    for eye in ("left", "right"):
        np.testing.assert_array_equal(a[eye].color, b[eye].color)
        np.testing.assert_array_equal(a[eye].depth, b[eye].depth)
        for name in AUX:
            np.testing.assert_array_equal(a[eye].aux[name], b[eye].aux[name], err_msg=f"{eye} {name}")


@pytest.mark.parametrize("case", ["raster", "traced", "chromatic", "shared chromatic"])
def test_msaa_frames_do_not_depend_on_when_the_round_count_is_known(gl, room, count_poll, case):
    """"traced": the room's own materials (mirror reflections, glossy, shadows: classify drops the
    skipped pixels from the effects' lists); "chromatic": three colour channel sets, each with its
    own count; "shared chromatic": the three sets cast together as sub-rays, one count. The reference
    is the old schedule: count read after the first round (waiting), empty slots shaded as background."""
    materials = "rayvr/assets/default_room.toml" if case == "traced" else None
    chromatic = case.endswith("chromatic")
    camera = Distorted(coefficients=((0.1, 0.0, 0.0), (0.2, 0.0, 0.0), (0.3, 0.0, 0.0))) if chromatic else None
    settings = RenderSettings(msaa=8, share_channel_shading=case == "shared chromatic")
    (ref, ref_rounds, _), (late, late_rounds, late_w), (skip, skip_rounds, skip_w) = frames(
        gl, room, count_poll, settings, [("wait", False), ("never", True), ("wait", True)], camera, materials)
    slots = primary_rays.msaa_slots(FramePlan(frozenset(), subsamples=8))
    assert len(ref_rounds) == (3 if case == "chromatic" else 1)
    for recorded, needed in ref_rounds:
        assert recorded == needed >= 2  # edges: several triangles in some pixels
    assert late_rounds == [(slots, needed) for _, needed in ref_rounds]  # never known: all the slots
    assert skip_rounds == ref_rounds
    assert max(n for _, n in ref_rounds) < slots  # so "never" recorded rounds past the count
    if case == "traced":  # classify left the skipped pixels out of the effects' lists
        (late_w, late_lists), (skip_w, skip_lists) = late_w, skip_w
        assert sum(late_lists.values()) == 0 and skip_lists["shadows"] > 0
    # the rounds past the count ran nothing (frame/passes/round_gate.py): no select wrote ROUND_SKIPPED
    # over slot 0's weights, as each pass over the whole frame did before the gate
    np.testing.assert_array_equal(late_w, skip_w)
    assert (skip_w >= 0).all() and (skip_w > 0).any()  # slot 0, the last real round, writes all
    assert np.isfinite(ref.left.aux["hdr"]).all() and ref.left.color.max() > 0
    assert_same(late, ref)
    assert_same(skip, ref)


def test_fence_poll_counts_rounds_and_renders_the_same(gl, room, count_poll):
    """The default schedule (a zero-timeout fence poll after each round) records between the
    needed rounds and msaa_slots, and gives the reference frame."""
    (ref, ref_rounds, _), (got, rounds, _) = frames(gl, room, count_poll, RenderSettings(msaa=4),
                                                    [("wait", True), ("fence", True)])
    ((recorded, needed),) = rounds
    assert [needed] == [n for _, n in ref_rounds] and needed <= recorded <= 4
    assert_same(got, ref)


def test_ssr_frames_keep_empty_slots_as_background(gl, room, count_poll):
    """ssr traces the round's whole depth pyramid: empty slots are not skipped there (another
    pixel's G-buffer is read), rounds past the count still are; frames identical early or late."""
    cfg = parse_config({"materials": {"floor": {"effect": "ssr"}}}, "<msaa ssr test>")
    plan = FramePlan(frozenset({"ssr"}), subsamples=4)
    assert not primary_rays.skips_empty_slots(plan)
    assert primary_rays.skips_empty_slots(FramePlan(frozenset({"glossy", "shadows"}), subsamples=4))
    (ref, ref_rounds, _), (late, late_rounds, _) = frames(gl, room, count_poll, RenderSettings(msaa=4),
                                                          [("wait", True), ("never", True)], materials=cfg)
    assert late_rounds[0][0] == 4 and ref_rounds[0][0] == ref_rounds[0][1]
    assert_same(late, ref)


def test_the_empty_slot_choice_keys_the_compiled_frame(gl, room):
    """skip_empty_slots compiles into the MSAA select (MSAA_SKIP_EMPTY), so it is part of the frame
    plan: a renderer given either value compiles its own graph for it, never the other's."""
    with Renderer(room, gl=gl, settings=RenderSettings(msaa=4)) as fast, \
            Renderer(room, gl=gl, settings=RenderSettings(msaa=4), skip_empty_slots=False) as reference:
        skip, shade = fast.plan(), reference.plan()
        assert skip.skip_empty_slots and not shade.skip_empty_slots and skip != shade
        assert primary_rays.skips_empty_slots(skip) and not primary_rays.skips_empty_slots(shade)
        assert fast.compiled(skip) is fast.compiled(skip) and fast.compiled(shade) is not fast.compiled(skip)
