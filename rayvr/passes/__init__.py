"""The frame's passes, one per file (each beside its shaders under rayvr/glsl/). Effects add
their own passes (rayvr/effects/); these are the core ones the graph picks from."""


def core_passes() -> list:
    from .accumulate import AccumulatePass
    from .bvh import BvhPass
    from .classify import ClassifyPass
    from .debug_view import DebugViewPass
    from .denoise import DenoisePass
    from .dof import DofPass
    from .gbuffer_resolve import GBufferResolvePass
    from .primary_rays import PrimaryRaysPass
    from .quadtree import QuadtreePass, QuadtreeVisitsPass
    from .second_layer import SecondLayerPass
    from .reuse import ReuseCopyPass, ReuseMapPass
    from .sample_accumulate import SampleAccumulatePass
    from .sample_pattern import SamplePatternPass
    from .sample_resolve import SampleResolvePass
    from .shade import ShadePass
    from .tonemap import TonemapPass
    from .visibility import VisibilityPass
    from .warp import WarpPass

    return [BvhPass(), VisibilityPass(), PrimaryRaysPass(), GBufferResolvePass(), ShadePass(), ClassifyPass(),
            AccumulatePass(), DenoisePass(), TonemapPass(), DebugViewPass(), QuadtreeVisitsPass(),
            QuadtreePass(effect="ssr"), SecondLayerPass(), ReuseMapPass(),
            ReuseCopyPass(), WarpPass(), DofPass(), SampleAccumulatePass(), SampleResolvePass(),
            SamplePatternPass()]


def radiance(plan) -> tuple[str, str]:
    """The frame's final linear colour (resource, GLSL image format): what tonemap shows and
    the `hdr` aux channel reads: with depth of field its image (passes/dof.py), else scene_radiance."""
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
    channel sets, sparse samples) the weighted sum of its rounds (passes/sample_resolve.py)."""
    return "frame_hdr" if plan.sampled else "hdr"
