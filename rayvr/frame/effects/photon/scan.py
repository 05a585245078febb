"""`photon_scan`: the hash grid's start indices, an exclusive prefix sum of its cell counts on the
GPU (frame/passes/prefix_scan.py Scan), in place: start[c] is the first sorted photon of cell c,
and the last word the number of photon slots."""
from __future__ import annotations

from ...graph import FramePlan, compose
from ...passes.prefix_scan import Scan
from .setup import PhotonPass, photon_setup


class PhotonScanPass(PhotonPass):
    name = "photon_scan"
    role = "the hash grid's start indices"

    def io(self, plan: FramePlan) -> list:
        return [compose("photon_start")]

    def setup(self, gl, plan: FramePlan) -> None:
        self.scan = Scan(gl.ctx)

    def execute(self, fc) -> None:
        self.scan.run(fc.resource("photon_start"), photon_setup(fc.sizing).grid.cells + 2)

    def release(self) -> None:
        self.scan.release()
