"""A stable LSD radix sort of (key, value) pairs on the GPU, 8 bits a round over the key bits asked
for (glsl/photon/radix_sort.comp: per-group digit histograms, their exclusive scan by
frame/passes/prefix_scan.py, a stable scatter). Stable and atomic-free in the order it makes, so
its result is the same each run. Sorts the photons by hash-grid cell (frame/effects/photon/sort.py,
which also gathers the photon records in that order: `permute`) and the wavefront's rays by
direction and origin (frame/passes/ray_order.py)."""
from __future__ import annotations

import moderngl

from ...gl import shaders
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO
from .prefix_scan import Scan, dispatch_shape, scan_words

SORT_GROUP = declare("SORT_GROUP", 256)  # invocations of a radix_sort.comp group: pairs it sorts
RADIX = declare("SORT_RADIX", 256, uint=True)  # digits of one pass (8 bits)


def sort_groups(n: int) -> tuple:
    """The sort's work groups (x, y); its digit table has RADIX words per group."""
    return dispatch_shape(n, SORT_GROUP)


def table_words(n: int) -> int:
    x, y = sort_groups(n)
    return scan_words(RADIX * x * y)


class RadixSort:
    """`counted`: the sort takes its pair count from a buffer the GPU wrote (sort(count=...))."""

    def __init__(self, ctx, counted: bool = False):
        self.ctx = ctx
        self.programs = [shaders.compute(ctx, "photon/radix_sort.comp", {"SORT_STAGE": s, "SORT_COUNTED": int(counted)})
                         for s in (0, 1, 2)]
        self.scan = Scan(ctx)
        self.counted = counted

    def sort(self, keys, alt, table, n: int, bits: int, count=None):
        """Sort n (key, slot) pairs by their low `bits` key bits; returns the buffer holding them.
        A counted sort's `count`: (buffer, k), the pairs are the first buffer.uvec4[k].w (<= n)."""
        if self.counted != (count is not None):
            raise ValueError("a counted sort takes its count (buffer, slot), no other sort does")
        shape = sort_groups(n)
        groups = shape[0] * shape[1]
        src, dst = keys, alt
        barrier = self.ctx.memory_barrier
        if count is not None:
            count[0].bind_to_storage_buffer(SSBO["sort_count"])
        for shift in range(0, bits, 8):
            for stage in (0, 1):
                src.bind_to_storage_buffer(SSBO["photon_keys"])
                dst.bind_to_storage_buffer(SSBO["photon_keys_alt"])
                table.bind_to_storage_buffer(SSBO["photon_scan"])
                prog = self.programs[stage]
                prog["item_count"].value, prog["digit_shift"].value = n, shift
                if count is not None:
                    prog["sort_count_slot"].value = count[1]
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
