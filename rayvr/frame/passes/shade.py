"""`shade`: the `raster` rung, direct light from the G-buffer (no shadows) into the HDR target, and
the background. It makes all of `hdr`; pixels of traced effects are left to their own passes,
which compose over it (glsl/shade/direct.comp skips them)."""
from __future__ import annotations

from ...gl import shaders
from ..effect_registry import EFFECTS
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.gpu_layout import IMAGE
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .primary_rays import bind_round_skip, round_skip_defines, round_skip_reads
from .reuse import bind_reuse, reuse_defines, reuse_reads


HDR = Texture("rgba16f")  # linear radiance, both eyes


class ShadePass(Pass):
    name = "shade"

    def why(self, plan: FramePlan) -> str | None:
        raster = plan.materials_using("raster")
        return f"effect raster ({', '.join(raster)}) and the background" if raster else "the background"

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), write("hdr", HDR)] + reuse_reads(plan) + round_skip_reads(plan)

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/direct.comp", {**camera_defines(plan), **reuse_defines(plan),
                                                                       **round_skip_defines(plan, listed=True)})
        # Pixels of traced effects get their colour from their own passes.
        self.traced_mask = sum(1 << EFFECTS[e].id for e in plan.effects if e in EFFECTS and EFFECTS[e].traced)

    def execute(self, fc) -> None:
        p = self.program
        set_eye_uniforms(p, fc)
        p["ambient"].value = tuple(fc.settings.ambient)
        p["background"].value = tuple(fc.settings.background)
        p["traced_effects"].value = self.traced_mask
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()
        bind_reuse(fc)
        bind_round_skip(fc)
        fc.resource("hdr").bind_to_image(IMAGE["hdr"], read=False, write=True)
        dispatch_per_pixel(fc, p, listed=True)

    def release(self) -> None:
        self.program.release()
