"""Debug views of the G-buffer channels and of the per-pixel effect ID."""
from __future__ import annotations

import numpy as np

from .. import shaders
from ..frame import FramePlan, Pass
from .compute import dispatch_per_pixel

# Order matches `view` in glsl/shade/debug_view.comp.
DEBUG_VIEWS = ("depth", "normal", "albedo", "roughness", "metallic", "emission", "material", "effect",
               "triangle", "position")


class DebugViewPass(Pass):
    name = "debug_view"
    reads = ("gbuffer",)
    writes = ("ldr",)

    def needed(self, plan: FramePlan) -> bool:
        return plan.view in DEBUG_VIEWS

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/debug_view.comp")

    def execute(self, fc) -> None:
        self.program["view"].value = DEBUG_VIEWS.index(fc.plan.view)
        lo = max(fc.eyes[0].near, 1e-6)
        hi = max(float(np.linalg.norm(fc.scene.bounds[1] - fc.scene.bounds[0])) * 2.0, lo * 10)
        self.program["depth_range"].value = (lo, hi)
        fc.gbuffer.bind_for_reading()
        fc.target("ldr").bind_to_image(1, read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
