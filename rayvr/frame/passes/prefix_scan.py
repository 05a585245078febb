"""An exclusive prefix sum in place on the GPU (glsl/photon/scan.comp), level by level: the photon
hash grid's start indices (frame/effects/photon/scan.py), the radix sort's digit table
(frame/passes/radix_sort.py); runs alone in tests against numpy (accel/photon_map.exclusive_scan)."""
from __future__ import annotations

import moderngl

from ...gl import shaders
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO

SCAN_GROUP = declare("SCAN_GROUP", 256)  # invocations of a scan.comp group
SCAN_ITEMS = declare("SCAN_ITEMS", 4)  # words each scans
SCAN_BLOCK = declare("SCAN_BLOCK", SCAN_GROUP * SCAN_ITEMS)  # words a group scans
MAX_GROUPS = 65535


def scan_levels(n: int) -> list:
    """(base, count, sums_base) per level of the scan of n words at word 0; the block totals of
    each level are the next level's words."""
    levels, base = [], 0
    while True:
        blocks = -(-max(n, 1) // SCAN_BLOCK)
        levels.append((base, n, base + n))
        if blocks == 1:
            return levels
        base, n = base + n, blocks


def scan_words(n: int) -> int:
    """Words the scan of n words needs: the words, then every level's block totals."""
    base, count, sums = scan_levels(n)[-1]
    return sums + 1


def groups_for(n: int, per_group: int) -> int:
    g = -(-max(n, 1) // per_group)
    if g > MAX_GROUPS:
        raise ValueError(f"{n} items need {g} work groups of {per_group}, more than {MAX_GROUPS}")
    return g


def dispatch_shape(n: int, per_group: int) -> tuple:
    """(x, y) work groups for n items, rows of at most MAX_GROUPS (shaders flatten x + y * width;
    groups past the last item do nothing)."""
    g = -(-max(n, 1) // per_group)
    x = min(g, MAX_GROUPS)
    return x, -(-g // x)


class Scan:
    """Exclusive prefix sum in place over the first n words of a buffer (with scan_words(n) words)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.programs = [shaders.compute(ctx, "photon/scan.comp", {"SCAN_STAGE": s}) for s in (0, 1)]

    def run(self, buffer, n: int, stage=None) -> None:
        buffer.bind_to_storage_buffer(SSBO["photon_scan"])
        levels = scan_levels(n)

        def go(prog, base, count, sums):
            prog["scan_base"].value, prog["sums_base"].value, prog["item_count"].value = base, sums, count
            prog.run(groups_for(count, SCAN_BLOCK))
            self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)

        for lv in levels:
            go(self.programs[0], *lv)
        for lv in reversed(levels[:-1]):
            go(self.programs[1], *lv)

    def release(self) -> None:
        for p in self.programs:
            p.release()
