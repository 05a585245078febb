"""`sample_resolve`: the accumulated colour of a sampled frame for display (`frame_hdr`, what
`tonemap` reads then), through the camera model's resolve (glsl/shade/sample_resolve.comp): a
sparse model's `reconstruction` fills the pixels between its samples, one dispatch per entry of its
`resolve_steps()`, in the float32 scratch `sample_fill` (its `reconstruct` is the numpy twin)."""
from __future__ import annotations

from ...gl import shaders
from ..cameras import CAMERA_MODELS
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.gpu_layout import IMAGE
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .sample_accumulate import sampling_reason

FRAME_HDR = Texture("rgba16f")
SAMPLE_FILL = Texture("rgba32f")  # a sparse model's samples and what its fill has made so far


class SampleResolvePass(Pass):
    name = "sample_resolve"

    def why(self, plan: FramePlan) -> str | None:
        return sampling_reason(plan) if plan.sampled else None

    def io(self, plan: FramePlan) -> list:
        fill = [write("sample_fill", SAMPLE_FILL)] if plan.reconstruct else []
        return [read("sample_sum"), write("frame_hdr", FRAME_HDR)] + fill

    def setup(self, gl, plan: FramePlan) -> None:
        self.reconstruct = plan.reconstruct
        resolve = {"CAMERA_RESOLVE_FILE": CAMERA_MODELS[plan.camera].reconstruction} if plan.reconstruct else {}
        self.program = shaders.compute(gl.ctx, "shade/sample_resolve.comp", {**resolve, **camera_defines(plan)})

    def execute(self, fc) -> None:
        set_eye_uniforms(self.program, fc)
        fc.resource("sample_sum").bind_to_image(IMAGE["sample_sum"], read=True, write=False)
        fc.resource("frame_hdr").bind_to_image(IMAGE["frame_hdr"], read=False, write=True)
        if not self.reconstruct:
            dispatch_per_pixel(fc, self.program)
            return
        fc.resource("sample_fill").bind_to_image(IMAGE["sample_fill"], read=True, write=True)
        if shaders.declares(self.program, "exposure"):
            self.program["exposure"].value = float(fc.settings.exposure)
        for step in fc.eyes[0].camera.resolve_steps():  # in the model's order; the last writes the frame
            for name, value in step.items():
                if shaders.declares(self.program, name):  # a uniform the compiler dropped is skipped
                    self.program[name].value = value
            dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
