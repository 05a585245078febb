"""`sample_resolve`: the accumulated colour of a sampled frame for display (`frame_hdr`, what
`tonemap` reads then), with a foveated camera's pixels between samples filled in, one dispatch per
dither level, coarse to fine, through the float32 `sample_fill` (glsl/shade/sample_resolve.comp;
frame/cameras/foveated.py reconstruct is its numpy twin)."""
from __future__ import annotations

from ...gl import shaders
from ..graph import FramePlan, Pass, Texture, read, write
from ..cameras.foveated import DITHER_BITS
from ...gl.gpu_layout import IMAGE
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .sample_accumulate import sampling_reason

FRAME_HDR = Texture("rgba16f")
SAMPLE_FILL = Texture("rgba32f")  # the samples and the dither lattices filled so far (RECONSTRUCT)


class SampleResolvePass(Pass):
    name = "sample_resolve"

    def why(self, plan: FramePlan) -> str | None:
        return sampling_reason(plan) if plan.sampled else None

    def io(self, plan: FramePlan) -> list:
        fill = [write("sample_fill", SAMPLE_FILL)] if plan.reconstruct else []
        return [read("sample_sum"), write("frame_hdr", FRAME_HDR)] + fill

    def setup(self, gl, plan: FramePlan) -> None:
        self.reconstruct = plan.reconstruct
        self.program = shaders.compute(gl.ctx, "shade/sample_resolve.comp",
                                       {"RECONSTRUCT": int(plan.reconstruct),
                                        **camera_defines(plan)})

    def execute(self, fc) -> None:
        set_eye_uniforms(self.program, fc)
        fc.resource("sample_sum").bind_to_image(IMAGE["sample_sum"], read=True, write=False)
        fc.resource("frame_hdr").bind_to_image(IMAGE["frame_hdr"], read=False, write=True)
        if not self.reconstruct:
            dispatch_per_pixel(fc, self.program)
            return
        fc.resource("sample_fill").bind_to_image(IMAGE["sample_fill"], read=True, write=True)
        self.program["exposure"].value = float(fc.settings.exposure)
        steps = [(DITHER_BITS, 0)] + [(k, step) for k in range(DITHER_BITS - 1, -1, -1) for step in (0, 1)]
        for level, step in steps:  # copy the samples, then fill coarse to fine: cell centres, edges
            self.program["resolve_level"].value = level
            if shaders.declares(self.program, "resolve_step"):
                self.program["resolve_step"].value = step
            dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
