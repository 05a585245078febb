"""Ray reordering in the wavefront: before a trace kernel of frame/passes/trace_effect.py
(closest hits of the paths, an event's shadow rays) every ray gets a key, its direction's octant in
the 3 high bits and under them the Morton code of its origin's cell in the scene's bounds
(glsl/rt/ray_order.glsl); the (key, ray) pairs are sorted on the GPU by the radix sort the photon
map uses (frame/passes/radix_sort.py), and invocation k of the trace kernel takes the k-th ray of
that order (glsl/rt/wave_fetch.glsl). Neighbouring invocations then start near each other in
the same octant and walk the same BVH nodes. Each ray's result still goes to its own slot and
nothing is summed across rays, so hits and images are exactly the unsorted wavefront's: only the
speed changes (`rayvr bench ... --ray-order none,morton`; on the GPU the sort costs more than it
saves, and with the default 1 GiB wave buffers the sorted shadow items thrash: docs/design.md).

A shadow-ray kernel traces an item's (pixel's or path's) rays in one invocation and sums them in
slot order, so the items are sorted, each by its first shadow ray of the chunk."""
from __future__ import annotations

import moderngl
import numpy as np

from ...gl import shaders
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO
from .prefix_scan import dispatch_shape
from .radix_sort import RadixSort, table_words
from . import compute  # noqa: F401  (declares RT_LOCAL_SIZE, which rt/ray_order.comp reads)
from ...accel import gpu  # noqa: F401  (declares BVH_MISS)


ORDER_AXIS_BITS = declare("ORDER_AXIS_BITS", 7)  # Morton bits per coordinate: 128^3 origin cells
OCTANT_BITS = 3
ORDER_KEY_BITS = 3 * ORDER_AXIS_BITS + OCTANT_BITS  # 24: three rounds of the 8-bit radix sort
# The key of an entry with nothing to trace (a path that has ended, an item with no shadow ray this
# chunk): the largest, so the stable sort puts them last, in index order.
ORDER_KEY_NONE = declare("ORDER_KEY_NONE", (1 << ORDER_KEY_BITS) - 1, uint=True)
ORDER_GROUP = declare("ORDER_GROUP", 256)  # invocations of a glsl/rt/ray_order.comp group
# ray_order.comp's ORDER_RAYS: the rays a key is made of
ORDER_PATHS, ORDER_SHADOWS = 1, 2
PAIR_BYTES = 8  # one (key, ray index) pair


def order_bounds(vertices: np.ndarray) -> tuple:
    """(lo, scale) as float32 triples: a scene-local point p lies in cell (p - lo) * scale, the
    scene's bounds cut into 2^ORDER_AXIS_BITS cells an axis (a flat axis into one)."""
    v = np.asarray(vertices, np.float32).reshape(-1, 3)
    lo = v.min(axis=0) if len(v) else np.zeros(3, np.float32)
    hi = v.max(axis=0) if len(v) else np.ones(3, np.float32)
    extent = (hi - lo).astype(np.float32)
    scale = np.where(extent > 0, np.float32(1 << ORDER_AXIS_BITS) / np.where(extent > 0, extent, 1), 0)
    return lo.astype(np.float32), scale.astype(np.float32)


def spread_bits(c: np.ndarray) -> np.ndarray:
    """The ORDER_AXIS_BITS low bits of each c, two zero bits after each (3-way interleave)."""
    c = np.asarray(c, np.uint32)
    out = np.zeros_like(c)
    for b in range(ORDER_AXIS_BITS):
        out |= ((c >> np.uint32(b)) & np.uint32(1)) << np.uint32(3 * b)
    return out


def order_keys(origins, directions, lo, scale) -> np.ndarray:
    """The keys glsl/rt/ray_order.glsl gives rays (numpy; the tests' reference): octant bits
    x<0, y<0, z<0 from high to low, then the Morton code of the origin's cell, x's bit highest."""
    o = np.asarray(origins, np.float32).reshape(-1, 3)
    d = np.asarray(directions, np.float32).reshape(-1, 3)
    top = np.float32((1 << ORDER_AXIS_BITS) - 1)
    cell = np.clip((o - np.float32(lo)) * np.float32(scale), np.float32(0), top).astype(np.uint32)
    morton = (spread_bits(cell[:, 0]) << np.uint32(2)) | (spread_bits(cell[:, 1]) << np.uint32(1)) | spread_bits(cell[:, 2])
    octant = ((d[:, 0] < 0).astype(np.uint32) << np.uint32(2)) | ((d[:, 1] < 0).astype(np.uint32) << np.uint32(1)) | \
        (d[:, 2] < 0).astype(np.uint32)
    return (octant << np.uint32(3 * ORDER_AXIS_BITS)) | morton


def pair_bytes(capacity: int) -> int:
    return PAIR_BYTES * capacity


def sort_table_bytes(capacity: int) -> int:
    return 4 * table_words(capacity)


class RayOrder:
    """The key kernels of one wavefront pass (its defines: the buffers' bindings) and the sort."""

    def __init__(self, ctx, defines: dict):
        self.ctx = ctx
        self.programs = {rays: shaders.compute(ctx, "rt/ray_order.comp", {**defines, "ORDER_RAYS": rays})
                         for rays in (ORDER_PATHS, ORDER_SHADOWS)}
        self.sorter = RadixSort(ctx, counted=True)  # over the batch's rays: a count on the GPU
        self._bounds = (None, None)  # (the vertices they were taken of, (lo, scale))

    def bounds(self, vertices) -> tuple:
        if self._bounds[0] is not vertices:
            self._bounds = (vertices, order_bounds(vertices))
        return self._bounds[1]

    def keys(self, program, vertices, pairs, capacity: int, **uniforms) -> None:
        """(key, ray) for the batch's rays (or items) now in the wave buffers, their count the w of
        wave_args[1] (or [wave_items]), at most `capacity`: the first entries of `pairs`."""
        lo, scale = self.bounds(vertices)
        program["order_lo"].value, program["order_scale"].value = tuple(map(float, lo)), tuple(map(float, scale))
        program["order_capacity"].value = capacity
        for k, v in uniforms.items():
            if shaders.declares(program, k):
                program[k].value = v
        pairs.bind_to_storage_buffer(SSBO["wave_order"])
        program.run(*dispatch_shape(capacity, ORDER_GROUP))
        self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)

    def sort(self, pairs, alt, table, capacity: int, wave_args, items: int):
        """The batch's pairs sorted by key (stable), their count the w of wave_args[items]; returns
        the buffer that holds them, bound as wave_order."""
        out = self.sorter.sort(pairs, alt, table, capacity, ORDER_KEY_BITS, count=(wave_args, items))
        out.bind_to_storage_buffer(SSBO["wave_order"])
        return out

    def release(self) -> None:
        for p in self.programs.values():
            p.release()
        self.sorter.release()
