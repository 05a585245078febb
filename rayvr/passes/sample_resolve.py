"""`sample_resolve`: the accumulated colour of a sampled frame for display (`frame_hdr`, what
`tonemap` reads then), with a foveated camera's pixels between samples filled in
(glsl/shade/sample_resolve.comp; cameras/foveated.py reconstruct is its numpy twin)."""
from __future__ import annotations

from .. import shaders
from ..frame import FramePlan, Pass, Texture, read, write
from ..gpu_layout import IMAGE
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .sample_accumulate import sampling_reason

FRAME_HDR = Texture("rgba16f")


class SampleResolvePass(Pass):
    name = "sample_resolve"

    def why(self, plan: FramePlan) -> str | None:
        return sampling_reason(plan) if plan.sampled else None

    def io(self, plan: FramePlan) -> list:
        return [read("sample_sum"), write("frame_hdr", FRAME_HDR)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/sample_resolve.comp",
                                       {"RECONSTRUCT": int(plan.reconstruct), **camera_defines(plan)})

    def execute(self, fc) -> None:
        set_eye_uniforms(self.program, fc)
        fc.resource("sample_sum").bind_to_image(IMAGE["sample_sum"], read=True, write=False)
        fc.resource("frame_hdr").bind_to_image(IMAGE["frame_hdr"], read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
