"""The frame's passes, one per file (each beside its shaders under rayvr/glsl/). Effects add
their own passes (rayvr/frame/effects/); the core ones the graph picks from are in core.py. This module
imports nothing, so any pass may ask it which resource holds the frame's colour."""


def radiance(plan) -> tuple[str, str]:
    """The frame's final linear colour (resource, GLSL image format): what tonemap shows and
    the `hdr` aux channel reads: with depth of field its image (frame/passes/dof.py), else scene_radiance."""
    if getattr(plan, "dof", False):
        return "hdr_dof", "rgba32f"
    return scene_radiance(plan)


def scene_radiance(plan) -> tuple[str, str]:
    """The frame's linear colour before depth of field: denoised, else accumulated, else the
    frame's own samples."""
    if plan.denoise:
        return "hdr_denoised", "rgba32f"
    if plan.accumulate:
        return "hdr_accum", "rgba32f"
    return frame_colour(plan), "rgba16f"


def frame_colour(plan) -> str:
    """This frame's own linear colour: `hdr`, or for a sampled frame (sub-rays per sample, colour
    channel sets, sparse samples) the weighted sum of its rounds (frame/passes/sample_resolve.py)."""
    return "frame_hdr" if plan.sampled else "hdr"
