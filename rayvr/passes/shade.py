"""`raster` shading: direct light from the G-buffer (no shadows) into the HDR target."""
from __future__ import annotations

from .. import shaders
from ..materials import EFFECTS
from ..frame import FramePlan, Pass
from .compute import dispatch_per_pixel, set_eye_uniforms


class ShadeDirectPass(Pass):
    name = "shade"
    reads = ("gbuffer",)
    writes = ("hdr",)

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/direct.comp")

    def execute(self, fc) -> None:
        p = self.program
        set_eye_uniforms(p, fc)
        p["ambient"].value = tuple(fc.settings.ambient)
        p["background"].value = tuple(fc.settings.background)
        # Pixels of ray-traced effects get their colour from their own pass (passes/raytrace.py).
        from .raytrace import traced_effects
        p["traced_effects"].value = sum(1 << EFFECTS[e].id for e in traced_effects(fc.plan))
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()
        fc.target("hdr").bind_to_image(0, read=False, write=True)
        dispatch_per_pixel(fc, p)

    def release(self) -> None:
        self.program.release()
