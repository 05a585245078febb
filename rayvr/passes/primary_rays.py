"""`primary_rays`: the ray-traced alternative to the visibility raster (RenderSettings.primary =
"rays"): each pixel's camera ray through the BVH (glsl/rt/primary.comp), leaving the triangle ID
and the hit distance (in position.w) for the G-buffer resolve."""
from __future__ import annotations

from .. import shaders
from ..accel.gpu import DEFAULT_BINDING, layout_defines
from ..frame import FramePlan, GBufferChannels, Pass, read, write
from ..gpu_layout import channel
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms


class PrimaryRaysPass(Pass):
    name = "primary_rays"

    def why(self, plan: FramePlan) -> str | None:
        return f"primary visibility = rays ({plan.camera} camera)" if plan.primary == "rays" else None

    def io(self, plan: FramePlan) -> list:
        return [read("bvh"), write("visibility", GBufferChannels(("triangle", "position")))]

    def setup(self, gl, plan: FramePlan) -> None:
        self.layout = plan.traversal[0]   # the primary rays' BVH layout
        self.program = shaders.compute(gl.ctx, "rt/primary.comp", {**layout_defines(DEFAULT_BINDING, self.layout),
                                                                   **camera_defines(plan)})

    def execute(self, fc) -> None:
        set_eye_uniforms(self.program, fc)
        fc.accel.layout(self.layout).bind(DEFAULT_BINDING)
        gb = fc.gbuffer
        for name in ("position", "triangle"):
            gb.textures[name].bind_to_image(channel(name).image, read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()
