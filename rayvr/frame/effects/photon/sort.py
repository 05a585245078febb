"""`photon_sort`: the photons in cell order, the hash grid's photon map. A stable LSD radix sort of
the (cell, slot) keys on the GPU, 8 bits a round over the bits the grid's keys use (glsl/photon/
radix_sort.comp: per-group digit histograms, their exclusive scan by glsl/photon/scan.comp,
a stable scatter), then the photon records gathered in that order. Stable and atomic-free in the
order it makes, so the map (and every sum over it) is the same each run."""
from __future__ import annotations

import moderngl

from ....gl import shaders
from ...graph import Buffer, FramePlan, compose, read, write
from ....gl.glsl_constants import declare
from ....gl.gpu_layout import SSBO
from .scan import Scan, dispatch_shape, scan_words
from .setup import PhotonPass, photon_setup

SORT_GROUP = declare("SORT_GROUP", 256)  # invocations of a radix_sort.comp group: pairs it sorts
RADIX = declare("SORT_RADIX", 256, uint=True)  # digits of one pass (8 bits)


def sort_groups(n: int) -> tuple:
    """The sort's work groups (x, y); its digit table has RADIX words per group."""
    return dispatch_shape(n, SORT_GROUP)


def table_words(n: int) -> int:
    x, y = sort_groups(n)
    return scan_words(RADIX * x * y)


class RadixSort:
    def __init__(self, ctx):
        self.ctx = ctx
        self.programs = [shaders.compute(ctx, "photon/radix_sort.comp", {"SORT_STAGE": s}) for s in (0, 1, 2)]
        self.scan = Scan(ctx)

    def sort(self, keys, alt, table, n: int, bits: int):
        """Sort n (key, slot) pairs by their low `bits` key bits; returns the buffer holding them."""
        shape = sort_groups(n)
        groups = shape[0] * shape[1]
        src, dst = keys, alt
        barrier = self.ctx.memory_barrier
        for shift in range(0, bits, 8):
            for stage in (0, 1):
                src.bind_to_storage_buffer(SSBO["photon_keys"])
                dst.bind_to_storage_buffer(SSBO["photon_keys_alt"])
                table.bind_to_storage_buffer(SSBO["photon_scan"])
                prog = self.programs[stage]
                prog["item_count"].value, prog["digit_shift"].value = n, shift
                prog.run(*shape)
                barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
                if stage == 0:
                    self.scan.run(table, RADIX * groups)
            src, dst = dst, src
        return src

    def permute(self, sorted_keys, photons, photon_map, n: int) -> None:
        sorted_keys.bind_to_storage_buffer(SSBO["photon_keys"])
        photons.bind_to_storage_buffer(SSBO["photons"])
        photon_map.bind_to_storage_buffer(SSBO["photon_map"])
        prog = self.programs[2]
        prog["item_count"].value = n
        prog.run(*sort_groups(n))
        self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)

    def release(self) -> None:
        for p in self.programs:
            p.release()
        self.scan.release()


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
