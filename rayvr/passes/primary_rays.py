"""`primary_rays`: the ray-traced alternative to the visibility raster (RenderSettings.primary =
"rays", and any camera model a rasterizer cannot sample, or sub-rays per sample): each sample's
camera ray through the BVH (glsl/rt/primary.comp), leaving the triangle ID, the sub-ray and the
hit distance for the G-buffer resolve.

Sampled frames (FramePlan.sampled) run in rounds (frame.py FrameGraph.execute): per colour
channel set, then per sub-ray (SSAA: each round casts one sub-ray of every sample) or per slot
of the distinct triangles the sub-rays hit (MSAA: the first round of a channel casts all N
sub-rays, keeps the distinct triangles with their coverage masks, and learns how many rounds
the frame needs, the most any pixel has; each round then shades one triangle per pixel). Each
round also writes every pixel's weight in the frame's colour (`sample_weight`), which
`sample_accumulate` applies. Slots run from the last to 0, so the G-buffer the frame keeps (for
depth and aux channels) is each pixel's most covered triangle.
"""
from __future__ import annotations

import numpy as np

from .. import shaders
from ..accel.gpu import DEFAULT_BINDING, layout_defines
from ..frame import Buffer, FramePlan, GBufferChannels, Pass, Texture, read, write
from ..gpu_layout import IMAGE, SSBO, channel
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms

MAX_SLOTS = 8  # distinct triangles kept per pixel (MSAA); sub-rays on further ones are dropped
SAMPLE_WEIGHT = Texture("r32f")


def msaa_slots(plan: FramePlan) -> int:
    return min(plan.samples, MAX_SLOTS)


def uses_msaa(plan: FramePlan) -> bool:
    return plan.samples > 1 and plan.shading == "msaa"


class PrimaryRaysPass(Pass):
    name = "primary_rays"
    timed_kernels = True

    def why(self, plan: FramePlan) -> str | None:
        if plan.primary != "rays":
            return None
        sub = f", {plan.samples} sub-rays per sample ({plan.shading})" if plan.samples > 1 else ""
        return f"primary visibility = rays ({plan.camera} camera{sub})"

    def io(self, plan: FramePlan) -> list:
        out = [read("bvh"), write("visibility", GBufferChannels(("triangle", "position")))]
        if plan.sampled:
            out.append(write("sample_weight", SAMPLE_WEIGHT))
        if uses_msaa(plan):
            slots = msaa_slots(plan)
            # Slot-major: slot k of every pixel, then slot k + 1 (coalesced writes and reads).
            out += [write("msaa_hits", Buffer(lambda s, n=slots: s.pixels * n * 16, f"{slots} x 16 bytes per pixel")),
                    write("msaa_count", Buffer(lambda s: 4, "4 bytes"))]
        return out

    def setup(self, gl, plan: FramePlan) -> None:
        self.layout = plan.traversal[0]   # the primary rays' BVH layout
        base = {**layout_defines(DEFAULT_BINDING, self.layout), **camera_defines(plan), "SAMPLED": int(plan.sampled),
                "MSAA_SLOTS": msaa_slots(plan)}
        self.msaa = uses_msaa(plan)
        self.programs = {mode: shaders.compute(gl.ctx, "rt/primary.comp", {**base, "PRIMARY_MODE": mode})
                         for mode in ((1, 2) if self.msaa else (0,))}

    def execute(self, fc) -> None:
        rnd = fc.round
        for program in self.programs.values():
            set_eye_uniforms(program, fc)
        fc.accel.layout(self.layout).bind(DEFAULT_BINDING)
        gb = fc.gbuffer
        for name in ("position", "triangle"):
            gb.textures[name].bind_to_image(channel(name).image, read=False, write=True)
        if "sample_weight" in fc.resources:
            fc.resource("sample_weight").bind_to_image(IMAGE["sample_weight"], read=False, write=True)
        if not self.msaa:
            if rnd.first:  # SSAA: one round per sub-ray; 1x: one
                rnd.start(fc.plan.samples)
            self.programs[0]["subsample"].value = rnd.slot
            fc.stage("cast", lambda: dispatch_per_pixel(fc, self.programs[0]))
            return
        fc.resource("msaa_hits").bind_to_storage_buffer(SSBO["msaa_hits"])
        count = fc.resource("msaa_count")
        count.bind_to_storage_buffer(SSBO["msaa_count"])
        if rnd.first:
            count.write(np.zeros(1, np.uint32).tobytes())
            fc.stage("trace", lambda: dispatch_per_pixel(fc, self.programs[1]))
            # The rounds this channel needs: the most distinct triangles any pixel saw (waits for the GPU).
            rnd.start(max(1, int(np.frombuffer(count.read(), np.uint32)[0])) if rnd.active else 1)
        self.programs[2]["msaa_slot"].value = rnd.slot
        fc.stage("select", lambda: dispatch_per_pixel(fc, self.programs[2]))

    def release(self) -> None:
        for p in self.programs.values():
            p.release()
