"""`tonemap`: exposure, tonemapper and sRGB encoding of `hdr` into the 8-bit output
(glsl/shade/tonemap.comp, common/color.glsl)."""
from __future__ import annotations

from ...gl import shaders
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.gpu_layout import IMAGE, TONEMAPPERS
from . import radiance
from .compute import dispatch_per_pixel


LDR = Texture("rgba8")  # what frames return and the preview shows


class TonemapPass(Pass):
    name = "tonemap"

    def why(self, plan: FramePlan) -> str | None:
        return "view = color" if plan.view == "color" else None

    def io(self, plan: FramePlan) -> list:
        return [read(radiance(plan)[0]), write("ldr", LDR)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.source, fmt = radiance(plan)  # accumulated or denoised colour where the plan has them
        self.program = shaders.compute(gl.ctx, "shade/tonemap.comp", {"HDR_FORMAT": fmt})

    def execute(self, fc) -> None:
        self.program["exposure"].value = float(fc.settings.exposure)
        self.program["tonemapper"].value = TONEMAPPERS.index(fc.settings.tonemapper)
        fc.resource(self.source).bind_to_image(IMAGE["hdr"], read=True, write=False)
        fc.resource("ldr").bind_to_image(IMAGE["ldr"], read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
