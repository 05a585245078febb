"""`photon_sort`: the photons in cell order, the hash grid's photon map: the (cell, slot) keys sorted
on the GPU by frame/passes/radix_sort.py over the bits the grid's keys use, then the photon records
gathered in that order. The sort is stable and atomic-free, so the map (and every sum over it) is
the same each run."""
from __future__ import annotations

from ...graph import Buffer, FramePlan, compose, read, write
from ...passes.radix_sort import RadixSort, table_words
from .setup import PhotonPass, photon_setup


class PhotonSortPass(PhotonPass):
    name = "photon_sort"
    role = "the hash grid's photon map"

    def io(self, plan: FramePlan) -> list:
        return [read("photons"), compose("photon_keys"),
                write("photon_map", Buffer(lambda s: 32 * photon_setup(s).slots, "32 B per photon slot, cell order")),
                write("photon_sort.keys", Buffer(lambda s: 8 * photon_setup(s).slots, "8 B per photon slot (ping-pong)")),
                write("photon_sort.table", Buffer(lambda s: 4 * table_words(photon_setup(s).slots),
                                                  "256 digit counts per 256 photon slots (+ scan totals)"))]

    def setup(self, gl, plan: FramePlan) -> None:
        self.sorter = RadixSort(gl.ctx)

    def execute(self, fc) -> None:
        ps = photon_setup(fc.sizing)
        keys = self.sorter.sort(fc.resource("photon_keys"), fc.resource("photon_sort.keys"),
                                fc.resource("photon_sort.table"), ps.slots, ps.grid.key_bits)
        self.sorter.permute(keys, fc.resource("photons"), fc.resource("photon_map"), ps.slots)

    def release(self) -> None:
        self.sorter.release()
