"""`gbuffer`: the compute resolve that fills every G-buffer channel from each pixel's triangle ID
and its own camera ray (glsl/gbuffer/resolve.comp): positions lie exactly on the pixel rays."""
from __future__ import annotations

from ...gl import shaders
from ..graph import FramePlan, GBufferChannels, Pass, read, write
from ...gl.gpu_layout import CHANNELS, UNIT
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .primary_rays import bind_round_skip, round_skip_defines, round_skip_reads

SURFACE_CHANNELS = tuple(c.name for c in CHANNELS if c.name != "depth")


class GBufferResolvePass(Pass):
    name = "gbuffer"

    def io(self, plan: FramePlan) -> list:
        return [read("visibility"), write("gbuffer", GBufferChannels(SURFACE_CHANNELS))] + round_skip_reads(plan)

    def setup(self, gl, plan: FramePlan) -> None:
        self.rays = plan.primary == "rays"  # triangle IDs from frame/passes/primary_rays.py
        self.program = shaders.compute(gl.ctx, "gbuffer/resolve.comp",
                                       {"PRIMARY_RAYS": int(self.rays), **camera_defines(plan),
                                        **round_skip_defines(plan, listed=True)})

    def execute(self, fc) -> None:
        set_eye_uniforms(self.program, fc)
        fc.gpu_scene.bind()
        fc.gpu_scene.textures.use(UNIT["base_color_textures"])
        fc.gbuffer.bind_for_writing(read_position=self.rays)  # primary rays left the hit distance in position.w
        bind_round_skip(fc)
        dispatch_per_pixel(fc, self.program, listed=True)

    def release(self) -> None:
        self.program.release()
