"""`denoise`: an edge-aware à-trous wavelet filter in the style of SVGF (Schied et al., HPG 2017),
over the pixels of the effects the material config denoises (glsl/post/denoise.comp; the numpy
reference is rayvr/reference/denoise.py).

It filters the accumulated colour (`hdr_accum`, frame/passes/accumulate.py) divided by the G-buffer's
albedo (demodulated, so texture and colour edges stay sharp), `iterations` times with a 5x5
B3-spline kernel whose taps lie 2^i pixels apart, each tap weighted by depth (against the
plane of the centre), normal, albedo and luminance scaled by the estimated standard deviation
of the noise (temporal moments of the samples, or a 7x7 spatial estimate before 4 samples), and
multiplies the albedo back. Before the filter, a pixel whose demodulated luminance lies more than
OUTLIER_SIGMAS standard deviations above the mean of its 5x5 neighbours on the same surface (a
firefly, which the luminance edge-stop would keep) is clamped to that bound. Only pixels of the
denoised effects are filtered and only taps on pixels of the same effect count, so a `raster`
wall never blurs into a `glossy` floor. Writes `hdr_denoised`, which tonemap shows.

The kernels run over 16x16 tiles of the image (not the classify pass's pixel lists): a work
group loads its tile and apron into workgroup memory once and takes every tap from there; an
à-trous step of 2^i works on the lattice of pixels 2^i apart, so its taps stay in the tile. A
tile without a denoised pixel stops after one fetch a pixel.
"""
from __future__ import annotations

from dataclasses import dataclass

import moderngl

from ...gl import shaders
from ...gl.glsl_constants import declare as declare_constant
from ..effect_registry import EFFECTS
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.gpu_layout import IMAGE
from ...options import plan_part
from ...render_options.denoise import DENOISE_ITERATIONS  # (quality/frame_knobs.py reads it here)
from .accumulate import ACCUM
from .compute import dispatch_per_pixel

DENOISE_TILE = 16  # one work group of glsl/post/denoise.comp filters 16x16 lattice points
# The outlier clamp (denoise.comp clamp_outlier; rayvr/reference/denoise.py clamp_outliers): the bound
# is the neighbours' weighted mean + OUTLIER_SIGMAS standard deviations of their luminance (the
# brightest neighbour left out). 4 keeps a smooth peak and a one-pixel bright line (checked in
# tests/test_denoise_outliers.py) and clamps the room's glossy-floor fireflies (docs/usage.md);
# 5 left as few on the room and took less light from path_room at 16 samples (0.3 % against 0.4).
OUTLIER_SIGMAS = declare_constant("DENOISE_OUTLIER_SIGMAS", 4.0)
# Its neighbourhood: 5x5 (3x3 darkened penumbrae: denoise.comp clamp_outlier says why).
OUTLIER_RADIUS = declare_constant("DENOISE_OUTLIER_RADIUS", 2)
# Neighbours' summed edge-stop weight below which a pixel is not judged (a thin object, an edge):
OUTLIER_MIN_WEIGHT = declare_constant("DENOISE_OUTLIER_MIN_WEIGHT", 2.0)


@dataclass(frozen=True)
class DenoiseParams:
    """The edge-stops' scales (SVGF's σz, σn, σl; σa ours, in base-colour units)."""

    sigma_depth: float = 1.0
    sigma_normal: float = 128.0
    sigma_luminance: float = 4.0
    sigma_albedo: float = 0.25


DEFAULTS = DenoiseParams()
GUIDE = Texture("rgba32ui")  # depth, octahedral normal, 8-bit base colour, effect: one fetch per tap
GRADIENT = Texture("rg32f")  # the view depth's screen-space gradient, once per frame
VARIANCE = Texture("r32f")  # the variance blurred 3x3, for each iteration after the first


class DenoisePass(Pass):
    name = "denoise"
    timed_kernels = True

    def why(self, plan: FramePlan) -> str | None:
        if not plan.denoise or plan.view != "color":
            return None
        return f"denoise on ({', '.join(plan.denoise)})"

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), read("hdr_accum"), read("accum_moments"),
                write("denoise.ping", ACCUM), write("denoise.pong", ACCUM), write("denoise.guide", GUIDE),
                write("denoise.gradient", GRADIENT), write("denoise.variance", VARIANCE), write("hdr_denoised", ACCUM)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.programs = {s: shaders.compute(gl.ctx, "post/denoise.comp", {"DENOISE_STAGE": s, "DENOISE_TILE": DENOISE_TILE})
                         for s in (0, 1, 2, 3, 4)}

    def execute(self, fc) -> None:
        iterations = int(fc.settings.denoise_iterations)
        mask = sum(1 << EFFECTS[name].id for name in fc.plan.denoise)
        fc.gbuffer.bind_for_reading()
        color, moments = fc.resource("hdr_accum"), fc.resource("accum_moments")
        out, ping, pong = fc.resource("hdr_denoised"), fc.resource("denoise.ping"), fc.resource("denoise.pong")
        guide = fc.resource("denoise.guide")
        color.bind_to_image(IMAGE["denoise_color"], read=True, write=False)
        moments.bind_to_image(IMAGE["denoise_moments"], read=True, write=False)
        fc.resource("denoise.gradient").bind_to_image(IMAGE["denoise_gradient"], read=True, write=True)
        fc.resource("denoise.variance").bind_to_image(IMAGE["denoise_variance"], read=True, write=True)
        for p in self.programs.values():
            for k, v in {**DEFAULTS.__dict__, "denoise_effects": mask}.items():
                if shaders.declares(p, k):
                    p[k].value = v
        w, h = fc.sizing.size

        def over_tiles(p, step=1):
            blocks = lambda n: -(-n // (DENOISE_TILE * step)) * step  # noqa: E731
            p.run(blocks(w), blocks(h), fc.sizing.layers)
            fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

        def passthrough():
            out.bind_to_image(IMAGE["denoise_out"], read=False, write=True)
            guide.bind_to_image(IMAGE["denoise_guide"], read=False, write=True)
            dispatch_per_pixel(fc, self.programs[0])
            guide.bind_to_image(IMAGE["denoise_guide"], read=True, write=False)

        def outliers():  # the demodulated colour, fireflies clamped, into pong
            pong.bind_to_image(IMAGE["denoise_out"], read=False, write=True)
            over_tiles(self.programs[4])

        def prepare():
            pong.bind_to_image(IMAGE["denoise_in"], read=True, write=False)
            ping.bind_to_image(IMAGE["denoise_out"], read=False, write=True)
            over_tiles(self.programs[1])

        fc.stage("passthrough", passthrough)
        fc.stage("outliers", outliers)
        fc.stage("prepare", prepare)
        src, dst = ping, pong
        for i in range(iterations):
            last = i == iterations - 1

            def iterate(i=i, src=src, dst=dst, last=last):
                src.bind_to_image(IMAGE["denoise_in"], read=True, write=False)
                if i > 0:  # the 3x3 blur of its input's variance (the first iteration blurs in its own tile)
                    over_tiles(self.programs[3])
                p = self.programs[2]
                p["step_size"].value = 1 << i
                p["last_iteration"].value = int(last)
                (out if last else dst).bind_to_image(IMAGE["denoise_out"], read=False, write=True)
                over_tiles(p, 1 << i)
            fc.stage(f"atrous{i}", iterate)
            src, dst = dst, src

    def release(self) -> None:
        for p in self.programs.values():
            p.release()


@plan_part("denoise")
def denoise_plan(ask, plan) -> None:
    """The effects the denoiser filters: the config's (or every traced one), in the colour view."""
    plan["denoise"] = tuple(sorted(ask.denoised)) if ask.color and ask.settings.denoise else ()
