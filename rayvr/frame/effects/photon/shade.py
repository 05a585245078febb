"""`rt_photon`: the `photon` materials' pixels in the wavefront of frame/passes/trace_effect.py (direct
light with shadow rays) plus the photon map's density estimate at each pixel
(glsl/effects/photon.glsl -> glsl/photon/estimate.glsl) in place of the constant ambient term:
indirect light and caustics. Reads the hash grid (photon_map, photon_start) and the kd-tree.
The pixel kernel is compiled per set of estimators the frame's materials use (PHOTON_ESTIMATORS):
the grid-only kernel carries no heap arrays and no kd-tree walk (fewer registers: faster)."""
from __future__ import annotations

from ....gl import shaders
from ...graph import FramePlan, read
from ....gl.gpu_layout import SSBO
from ...passes.trace_effect import TraceEffectPass
from .cells import set_grid_uniforms
from .setup import photon_setup


class PhotonShadePass(TraceEffectPass):
    def setup(self, gl, plan) -> None:
        super().setup(gl, plan)
        self.variants = {15: self.programs["pixel"]}  # estimator bits -> pixel kernel (15: all four)

    def execute(self, fc) -> None:
        bits = photon_setup(fc.sizing).estimators
        if bits not in self.variants:
            self.variants[bits] = shaders.compute(fc.gl.ctx, "rt/wave_shade.comp",
                                                  {**self.shade_defines, "WAVE_STAGE": 3, "PHOTON_ESTIMATORS": bits})
        self.programs["pixel"] = self.variants[bits]
        super().execute(fc)

    def release(self) -> None:
        self.programs.pop("pixel")  # one of the variants
        for p in self.variants.values():
            p.release()
        super().release()

    def io(self, plan: FramePlan) -> list:
        return super().io(plan) + [read("photon_map"), read("photon_start"), read("photon_kdtree")]

    def bind_extra(self, fc) -> None:
        ps = photon_setup(fc.sizing)
        fc.resource("photon_map").bind_to_storage_buffer(SSBO["photon_map"])
        fc.resource("photon_start").bind_to_storage_buffer(SSBO["photon_scan"])
        fc.resource("photon_kdtree").bind_to_storage_buffer(SSBO["photon_kdtree"])
        for p in self.running.values():
            set_grid_uniforms(p, ps.grid)
