"""`rt_photon`: the `photon` materials' pixels in the wavefront of passes/trace_effect.py (direct
light with shadow rays) plus the photon map's density estimate at each pixel
(glsl/effects/photon.glsl -> glsl/photon/estimate.glsl) in place of the constant ambient term:
indirect light and caustics. Reads the hash grid (photon_map, photon_start) and the kd-tree."""
from __future__ import annotations

from ..effects.photon import photon_setup
from ..frame import FramePlan, read
from ..gpu_layout import SSBO
from .photon_cells import set_grid_uniforms
from .trace_effect import TraceEffectPass


class PhotonShadePass(TraceEffectPass):
    def io(self, plan: FramePlan) -> list:
        return super().io(plan) + [read("photon_map"), read("photon_start"), read("photon_kdtree")]

    def bind_extra(self, fc) -> None:
        ps = photon_setup(fc.sizing)
        fc.resource("photon_map").bind_to_storage_buffer(SSBO["photon_map"])
        fc.resource("photon_start").bind_to_storage_buffer(SSBO["photon_scan"])
        fc.resource("photon_kdtree").bind_to_storage_buffer(SSBO["photon_kdtree"])
        for p in self.programs.values():
            set_grid_uniforms(p, ps.grid)
            if "photon_radius_scale" in p:
                p["photon_radius_scale"].value = ps.radius_scale
