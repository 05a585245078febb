"""Resolve: exposure + tonemapper + sRGB into the 8-bit output (glsl/common/color.glsl)."""
from __future__ import annotations

from .. import shaders
from ..frame import FramePlan, Pass
from .compute import dispatch_per_pixel

TONEMAPPERS = {"clamp": 0, "reinhard": 1, "aces": 2}


class ResolvePass(Pass):
    name = "resolve"
    reads = ("hdr",)
    writes = ("ldr",)

    def needed(self, plan: FramePlan) -> bool:
        return plan.view == "color"

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/tonemap.comp")

    def execute(self, fc) -> None:
        self.program["exposure"].value = float(fc.settings.exposure)
        self.program["tonemapper"].value = TONEMAPPERS[fc.settings.tonemapper]
        fc.target("hdr").bind_to_image(0, read=True, write=False)
        fc.target("ldr").bind_to_image(1, read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
