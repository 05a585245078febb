"""`sample_accumulate`: a sampled frame's colour (FramePlan.sampled: sub-rays per sample, colour
channel sets, sparse foveated samples) is the weighted sum of its rounds' `hdr`
(glsl/shade/sample_accumulate.comp). The frame graph runs this pass and everything it depends on
once per round (frame/graph.py Round): SSAA shades every sub-ray, MSAA every distinct triangle of a
pixel once, a chromatic camera each colour channel on its own rays."""
from __future__ import annotations

from ...gl import shaders
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.gpu_layout import IMAGE
from .compute import dispatch_per_pixel
from .primary_rays import bind_round_skip, skips_rounds

SAMPLE_SUM = Texture("rgba32f")


def sampling_reason(plan: FramePlan) -> str:
    parts = []
    if plan.subsamples > 1:
        parts.append(f"{plan.subsamples} sub-rays per sample, {plan.shading}")
    if plan.channels > 1:
        parts.append(f"{plan.channels} colour channel sets ({plan.camera} camera)")
    if plan.reconstruct:
        parts.append(f"sparse samples ({plan.camera} camera)")
    return "; ".join(parts)


class SampleAccumulatePass(Pass):
    name = "sample_accumulate"

    def why(self, plan: FramePlan) -> str | None:
        return sampling_reason(plan) if plan.sampled else None

    def io(self, plan: FramePlan) -> list:
        return [read("hdr"), read("sample_weight"), write("sample_sum", SAMPLE_SUM)] + (
            [read("channel_weight")] if plan.share_channels else []) + (
            [read("round_tiles")] if skips_rounds(plan) else [])

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/sample_accumulate.comp",
                                       {"SHARE_CHANNELS": int(plan.share_channels),
                                        "ROUND_TILES": int(skips_rounds(plan))})

    def execute(self, fc) -> None:
        rnd = fc.round
        self.program["first"].value = int(rnd.index == 0)
        if shaders.declares(self.program, "channel"):   # (shared channel shading weighs each channel on its own)
            self.program["channel"].value = rnd.channel if fc.plan.channels > 1 else -1
        fc.resource("hdr").bind_to_image(IMAGE["hdr"], read=True, write=False)
        fc.resource("sample_weight").bind_to_image(IMAGE["sample_weight"], read=True, write=False)
        fc.resource("sample_sum").bind_to_image(IMAGE["sample_sum"], read=True, write=True)
        if fc.plan.share_channels:
            fc.resource("channel_weight").bind_to_image(IMAGE["channel_weight"], read=True, write=False)
        bind_round_skip(fc)  # the round's listed tiles (and the weight again) where rounds skip pixels
        # the frame's first round starts every pixel's sum, skipped or not: the whole frame
        dispatch_per_pixel(fc, self.program, listed=rnd.index > 0)

    def release(self) -> None:
        self.program.release()
