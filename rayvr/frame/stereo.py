"""Stereo modes: how the second eye is made (DESIGN.md "Stereo").

    dual    both eyes fully: one layered G-buffer, every pass over both layers
    reuse   the photon-mapping paper's §3.3: the left eye is shaded; each left hit the right eye
            also sees (visibility test against the right eye's G-buffer) gives its shading to the
            right-eye pixel it lands on (frame/passes/reuse.py); only the right-eye pixels left empty are
            shaded (classify and shade skip the others), for every effect
    warp    Widmer et al. 2015 §5.1: one central view (between the eyes) is rendered and shaded;
            each eye is synthesized by tracing its camera rays through the central view's quadtree
            (frame/passes/warp.py), two depth layers by default (the second layer's surfaces shaded
            as the `raster` rung); rays that pass behind every layer or leave the central image
            are holes, counted and inpainted from the background side

The mode is a render setting (`RenderSettings.stereo`, `--stereo`); it enters the FramePlan, so
the frame graph compiles the passes the mode needs and no others. A frame of one eye has no
second eye to make: it is always `dual`. `warp` and `reuse` project points between planar
frusta, so they need the pinhole camera model.
"""
from __future__ import annotations


from ..options import PlanRefusal, plan_part
from ..render_options.stereo import STEREO_MODES, STEREO

PLANAR_MODES = ("warp", "reuse")  # need a planar (pinhole) projection
WARP_OUTPUT = "stereo_ldr"  # the warped eyes (the frame's output under `warp`)
WARP_DEPTH = "stereo_depth"  # each warped eye's linear view depth


def check_mode(mode: str) -> str:
    return STEREO.check(mode)


def effective_mode(mode: str, eyes: int, camera) -> str:
    """The mode a frame of `eyes` eyes through `camera` (a rayvr.frame.cameras model) uses: one eye is
    always `dual`; a camera a rasterizer cannot sample is refused for warp/reuse."""
    check_mode(mode)
    if eyes != 2:
        return "dual"
    if mode in PLANAR_MODES and not camera.rasterizable:
        raise PlanRefusal(f"stereo mode {mode!r} reprojects between planar frusta: it needs the pinhole camera, "
                          f"not {camera.name!r}", "use", ("stereo", "dual"))
    return mode


@plan_part("stereo", after=("sampling",))
def stereo_plan(ask, plan) -> None:
    """How the second eye is made; warp renders one central view (one layer, its own output) with
    the depth layers it asks for."""
    stereo = effective_mode(ask.settings.stereo, ask.eyes, ask.camera)
    if stereo != "dual" and plan["subsamples"] > 1:  # their passes read one G-buffer, not a frame of rounds
        raise PlanRefusal(f"stereo mode {stereo!r} reprojects one sample per pixel: it cannot take "
                          f"{plan['subsamples']} sub-rays a sample", "use", ("stereo", "dual"))
    warp = stereo == "warp"
    plan.update(stereo=stereo, eyes=1 if warp else ask.eyes, output=WARP_OUTPUT if warp else "ldr",
                depth_layers=max(ask.depth_layers, ask.settings.warp_layers if warp else 1))


def rendered_eyes(rig, eyes: str, mode: str) -> list:
    """The eyes whose G-buffer a frame renders: the central eye under `warp`, else the asked ones."""
    return [rig.eye("center")] if mode == "warp" else rig.eyes(eyes)
