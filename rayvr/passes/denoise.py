"""`denoise`: an edge-aware à-trous wavelet filter in the style of SVGF (Schied et al., HPG 2017),
over the pixels of the effects the material config denoises (glsl/post/denoise.comp; the numpy
reference is rayvr/numpy_denoise.py).

It filters the accumulated colour (`hdr_accum`, passes/accumulate.py) divided by the G-buffer's
albedo (demodulated, so texture and colour edges stay sharp), `iterations` times with a 5x5
B3-spline kernel whose taps lie 2^i pixels apart, each tap weighted by depth (against the
plane of the centre), normal, albedo and luminance scaled by the estimated standard deviation
of the noise (temporal moments of the samples, or a 7x7 spatial estimate before 4 samples), and
multiplies the albedo back. Only the listed pixels of the denoised effects are filtered (indirect
dispatches over the classify pass's lists) and only taps on pixels of the same effect count, so
a `raster` wall never blurs into a `glossy` floor. Writes `hdr_denoised`, which tonemap shows.
"""
from __future__ import annotations

from dataclasses import dataclass

import moderngl

from .. import shaders
from ..effects import traced_effects
from ..frame import FramePlan, Pass, Texture, read, write
from ..gpu_layout import IMAGE
from .accumulate import ACCUM
from .classify import ARGS_BYTES, bind_lists
from .compute import dispatch_per_pixel


@dataclass(frozen=True)
class DenoiseParams:
    """The edge-stops' scales (SVGF's σz, σn, σl; σa ours, in base-colour units)."""

    sigma_depth: float = 1.0
    sigma_normal: float = 128.0
    sigma_luminance: float = 4.0
    sigma_albedo: float = 0.25


DEFAULTS = DenoiseParams()
GUIDE = Texture("rgba32ui")  # depth, octahedral normal, 8-bit base colour, effect: one fetch per tap


class DenoisePass(Pass):
    name = "denoise"
    timed_kernels = True

    def why(self, plan: FramePlan) -> str | None:
        if not plan.denoise or plan.view != "color":
            return None
        return f"denoise on ({', '.join(plan.denoise)})"

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), read("rt_lists"), read("rt_list_args"), read("hdr_accum"), read("accum_moments"),
                write("denoise.ping", ACCUM), write("denoise.pong", ACCUM), write("denoise.guide", GUIDE),
                write("hdr_denoised", ACCUM)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.programs = {s: shaders.compute(gl.ctx, "post/denoise.comp", {"DENOISE_STAGE": s}) for s in (0, 1, 2)}
        self.slots = {e.name: i for i, e in enumerate(traced_effects())}

    def execute(self, fc) -> None:
        iterations = int(fc.settings.denoise_iterations)
        denoised = fc.plan.denoise
        params = DEFAULTS
        fc.gbuffer.bind_for_reading()
        bind_lists(fc)
        color, moments = fc.resource("hdr_accum"), fc.resource("accum_moments")
        out, ping, pong = fc.resource("hdr_denoised"), fc.resource("denoise.ping"), fc.resource("denoise.pong")
        guide = fc.resource("denoise.guide")
        color.bind_to_image(IMAGE["denoise_color"], read=True, write=False)
        moments.bind_to_image(IMAGE["denoise_moments"], read=True, write=False)
        args = fc.resource("rt_list_args")
        w, h = fc.gbuffer.size
        for p in self.programs.values():
            for k, v in params.__dict__.items():
                if k in p:
                    p[k].value = v
            if "rt_capacity" in p:
                p["rt_capacity"].value = w * h * fc.gbuffer.layers

        def over_lists(p):
            for name in denoised:
                p["denoise_slot"].value = self.slots[name]
                p.run_indirect(args, offset=ARGS_BYTES * self.slots[name])
            fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

        def passthrough():
            out.bind_to_image(IMAGE["denoise_out"], read=False, write=True)
            guide.bind_to_image(IMAGE["denoise_guide"], read=False, write=True)
            dispatch_per_pixel(fc, self.programs[0])
            guide.bind_to_image(IMAGE["denoise_guide"], read=True, write=False)

        def prepare():
            ping.bind_to_image(IMAGE["denoise_out"], read=False, write=True)
            over_lists(self.programs[1])

        fc.stage("passthrough", passthrough)
        fc.stage("prepare", prepare)
        src, dst = ping, pong
        for i in range(iterations):
            last = i == iterations - 1

            def iterate(i=i, src=src, dst=dst, last=last):
                p = self.programs[2]
                p["step_size"].value = 1 << i
                p["last_iteration"].value = int(last)
                src.bind_to_image(IMAGE["denoise_in"], read=True, write=False)
                (out if last else dst).bind_to_image(IMAGE["denoise_out"], read=False, write=True)
                over_lists(p)
            fc.stage(f"atrous{i}", iterate)
            src, dst = dst, src

    def release(self) -> None:
        for p in self.programs.values():
            p.release()

