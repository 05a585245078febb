"""`debug_view`: a G-buffer channel or the per-pixel effect ID as the 8-bit output
(glsl/shade/debug_view.comp)."""
from __future__ import annotations

import numpy as np

from ...gl import shaders
from ..graph import FramePlan, Pass, read, write
from ...gl.gpu_layout import DEBUG_VIEWS, IMAGE
from .compute import dispatch_per_pixel
from .tonemap import LDR


class DebugViewPass(Pass):
    name = "debug_view"

    def why(self, plan: FramePlan) -> str | None:
        return f"view = {plan.view}" if plan.view in DEBUG_VIEWS else None

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), write("ldr", LDR)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "shade/debug_view.comp")

    def execute(self, fc) -> None:
        self.program["view"].value = DEBUG_VIEWS.index(fc.plan.view)
        lo = max(fc.eyes[0].near, 1e-6)
        hi = max(float(np.linalg.norm(fc.scene.bounds[1] - fc.scene.bounds[0])) * 2.0, lo * 10)
        self.program["depth_range"].value = (lo, hi)
        fc.gbuffer.bind_for_reading()
        fc.resource("ldr").bind_to_image(IMAGE["ldr"], read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
