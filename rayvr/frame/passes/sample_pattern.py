"""`sample_pattern`: the `samples` view, where the camera model puts its samples (density, a
10-degree grid of its rays, one colour per channel set; glsl/cameras/sample_pattern.comp)."""
from __future__ import annotations

from types import SimpleNamespace

from ...gl import shaders
from ..graph import FramePlan, Pass, read, write
from ...gl.gpu_layout import IMAGE
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .tonemap import LDR


class SamplePatternPass(Pass):
    name = "sample_pattern"

    def why(self, plan: FramePlan) -> str | None:
        return f"view = samples ({plan.camera} camera)" if plan.view == "samples" else None

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), write("ldr", LDR)]  # the G-buffer: frames come with their depth

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "cameras/sample_pattern.comp", camera_defines(plan))

    def execute(self, fc) -> None:
        fc.resource("ldr").bind_to_image(IMAGE["ldr"], read=True, write=True)
        channels = fc.plan.channels
        for c in range(channels):
            view = SimpleNamespace(eyes=fc.eyes, scene=fc.scene, gl=fc.gl, round=SimpleNamespace(channel=c))
            set_eye_uniforms(self.program, view)
            self.program["channel_out"].value = c if channels > 1 else -1
            dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
