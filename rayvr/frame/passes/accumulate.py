"""`accumulate`: the running mean of the frame's samples while nothing changes (glsl/post/accumulate.comp).

It reads the frame's `hdr` (one sample per pixel of every sampled effect) and writes `hdr_accum`
(rgb mean, alpha the pixel's sample count) and `accum_moments` (mean demodulated luminance and
its square, for the denoiser's variance; view depth and material, for reprojection). Which sample
a frame is and when to start over is rayvr/frame/accumulation.py's decision (fc.samples). Both
outputs are also the history: the pool keeps them between frames. With temporal reprojection on
(RenderSettings.temporal) the history is read where each surface point was in the previous frame,
so it lives in two textures of its own that swap every frame (the pass reads one, writes the other).
"""
from __future__ import annotations

from ...gl import shaders
from ..accumulation import HISTORY_CAP, temporal_problem
from ...options import PlanRefusal, plan_part
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import IMAGE
from . import frame_colour
from .compute import dispatch_per_pixel


# The albedo floor of demodulation (glsl/post/demodulate.glsl, here and in the denoiser; Falcor uses
# 0.001), numpy_denoise's too.
DEMODULATE_FLOOR = declare("DEMODULATE_FLOOR", 0.001)
ACCUM = Texture("rgba32f")  # float32: a mean over thousands of samples keeps its last bits
NO_CAP = 3.0e38  # still camera: the exact running mean, however many samples


class AccumulatePass(Pass):
    name = "accumulate"

    def why(self, plan: FramePlan) -> str | None:
        return "accumulation of samples" if plan.accumulate and plan.view == "color" else None

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), read(frame_colour(plan)), write("hdr_accum", ACCUM), write("accum_moments", ACCUM)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.gl = gl
        self.programs = {h: shaders.compute(gl.ctx, "post/accumulate.comp", {"ACCUM_HISTORY": h}) for h in (0, 1)}
        self.history: dict = {}  # temporal history: (size, layers) -> [(colour, moments), (colour, moments)]
        self.parity = 0

    def _history(self, fc):
        key = (fc.gbuffer.size, fc.gbuffer.layers)
        if key not in self.history:
            self._release_history()
            w, h = fc.gbuffer.size
            make = lambda: fc.gl.ctx.texture_array((w, h, fc.gbuffer.layers), 4, dtype="f4")  # noqa: E731
            self.history = {key: [(make(), make()), (make(), make())]}
        return self.history[key]

    def execute(self, fc) -> None:
        state = fc.samples
        temporal = bool(fc.settings.temporal)  # (Renderer.plan refuses it where the camera cannot reproject)
        p = self.programs[int(temporal)]
        # a moved camera this pass cannot reproject for starts over
        p["reset"].value = int(state is None or state.reset or (state.moved and not temporal))
        fc.gbuffer.bind_for_reading()
        out, moments = fc.resource("hdr_accum"), fc.resource("accum_moments")
        fc.resource(frame_colour(fc.plan)).bind_to_image(IMAGE["hdr"], read=True, write=False)
        out.bind_to_image(IMAGE["accum_out"], read=False, write=True)
        moments.bind_to_image(IMAGE["accum_moments_out"], read=False, write=True)
        if temporal:
            pairs = self._history(fc)
            src, dst = pairs[self.parity], pairs[1 - self.parity]
            self.parity ^= 1
            moved = state is not None and state.moved and bool(state.previous)
            p["reproject"].value = int(moved)
            p["history_cap"].value = float(HISTORY_CAP) if moved else NO_CAP
            if moved:
                for k in ("eye_position", "eye_rotation", "eye_tangents"):
                    if shaders.declares(p, f"prev_{k}"):
                        p[f"prev_{k}"].write(state.previous[k].tobytes())
            src[0].bind_to_image(IMAGE["accum_in"], read=True, write=False)
            src[1].bind_to_image(IMAGE["accum_moments_in"], read=True, write=False)
            dst[0].bind_to_image(IMAGE["accum_history_out"], read=False, write=True)
            dst[1].bind_to_image(IMAGE["accum_history_moments_out"], read=False, write=True)
        else:  # the history is this pixel's own: read where it is written
            p["reproject"].value = 0
            p["history_cap"].value = NO_CAP
            out.bind_to_image(IMAGE["accum_in"], read=True, write=False)
            moments.bind_to_image(IMAGE["accum_moments_in"], read=True, write=False)
        dispatch_per_pixel(fc, p)

    def _release_history(self) -> None:
        for pairs in self.history.values():
            for pair in pairs:
                for t in pair:
                    t.release()
        self.history = {}

    def release(self) -> None:
        for p in self.programs.values():
            p.release()
        self._release_history()


@plan_part("accumulate", after=("denoise",))
def accumulate_plan(ask, plan) -> None:
    """A running mean of samples where asked or where the denoiser reads one; temporal reprojection
    follows only a camera with planar frusta."""
    st = ask.settings
    plan["accumulate"] = ask.color and (ask.accumulate or st.accumulate or bool(plan["denoise"]))
    problem = temporal_problem(ask.camera) if plan["accumulate"] and st.temporal else None
    if problem:
        raise PlanRefusal(problem, "leave out", ("temporal", True))
