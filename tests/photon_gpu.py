"""A test harness: the photon map's GPU steps run alone on photons given from numpy, the same
kernels the frame graph runs (rayvr/frame/effects/photon/ cells.py, scan.py, sort.py, kdtree.py;
tests/glsl/photon_query.comp for radius queries), so each can be held to its numpy reference in
rayvr/accel/photon_map.py (tests/test_photon_map.py)."""
from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from rayvr.gl import shaders
from rayvr.accel.photon_map import PHOTON_WORDS, GridShape
from rayvr.frame.effects.photon.cells import CellKeys, set_grid_uniforms
from rayvr.frame.effects.photon.kdtree import kdtree_records
from rayvr.frame.passes.prefix_scan import scan_words
from rayvr.frame.passes.radix_sort import RadixSort, table_words
from rayvr.gl.glsl_constants import declare
from rayvr.gl.gpu_layout import SSBO

TEST_GLSL = Path(__file__).parent / "glsl"  # the tests' own shaders (rayvr/glsl/ for their includes)
QUERY_GROUP = declare("PHOTON_QUERY_GROUP", 64)  # query points a photon_query.comp group answers


class GpuPhotonMap:
    """Photon records (N, 8) uint32 uploaded; build() the hash grid, kdtree() the baseline, query()."""

    def __init__(self, ctx, records: np.ndarray, grid: GridShape):
        self.ctx = getattr(ctx, "ctx", ctx)
        self.n = len(records)
        self.grid = grid
        buf = lambda nbytes, data=None: self.ctx.buffer(data if data is not None else bytes(max(nbytes, 4)))
        self.photons = buf(0, np.ascontiguousarray(records, np.uint32).tobytes())
        self.keys = buf(8 * self.n)
        self.alt = buf(8 * self.n)
        self.start = buf(4 * scan_words(grid.cells + 2))
        self.table = buf(4 * table_words(self.n))
        self.map = buf(4 * PHOTON_WORDS * self.n)
        self.kd = None
        self.cells, self.sorter = CellKeys(self.ctx), RadixSort(self.ctx)
        self._queries: dict = {}

    def build(self, keep_keys: bool = False) -> None:
        """cells + counts, prefix sum -> start indices, radix sort, gather: the hash grid.
        keep_keys: read the (cell, slot) keys back before the sort reuses their buffer (.cell_keys)."""
        self.cells.run(self.photons, self.keys, self.start, self.n, self.grid)
        if keep_keys:
            self.cell_keys = self.read_u32(self.keys, self.n, 2).copy()
        self.sorter.scan.run(self.start, self.grid.cells + 2)
        self.sorted_keys = self.sorter.sort(self.keys, self.alt, self.table, self.n, self.grid.key_bits)
        self.sorter.permute(self.sorted_keys, self.photons, self.map, self.n)

    def kdtree(self) -> np.ndarray:
        """Build the kd-tree on the CPU from the photons on the GPU, upload it; returns its records."""
        rec = kdtree_records(self.photons.read())
        self.kd = self.ctx.buffer(rec.tobytes())
        return rec

    def read_u32(self, buffer, count: int, width: int = 1) -> np.ndarray:
        return np.frombuffer(buffer.read(), np.uint32)[: count * width].reshape(-1, width).squeeze()

    def query(self, points: np.ndarray, radius: float, capacity: int = 256, kdtree: bool = False) -> list:
        """Per point, the indices (into the photon map, or into the kd-tree's array) within radius."""
        key = bool(kdtree)
        if key not in self._queries:
            self._queries[key] = shaders.compute(self.ctx, "photon_query.comp", {"QUERY_KDTREE": int(key)}, root=TEST_GLSL)
        prog = self._queries[key]
        pts = np.zeros((len(points), 4), np.float32)
        pts[:, :3] = points
        q = self.ctx.buffer(pts.tobytes())
        found = self.ctx.buffer(bytes(4 * capacity * len(points)))
        counts = self.ctx.buffer(bytes(4 * len(points)))
        q.bind_to_storage_buffer(SSBO["photon_queries"])
        found.bind_to_storage_buffer(SSBO["photon_found"])
        counts.bind_to_storage_buffer(SSBO["photon_query_counts"])
        self.map.bind_to_storage_buffer(SSBO["photon_map"])
        self.start.bind_to_storage_buffer(SSBO["photon_scan"])
        (self.kd or self.map).bind_to_storage_buffer(SSBO["photon_kdtree"])
        set_grid_uniforms(prog, self.grid)
        for k, v in {"query_count": len(points), "query_capacity": capacity, "query_radius": float(radius)}.items():
            if k in prog:
                prog[k].value = v
        prog.run(-(-len(points) // QUERY_GROUP))
        self.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)
        c = np.frombuffer(counts.read(), np.uint32)
        f = np.frombuffer(found.read(), np.uint32).reshape(len(points), capacity)
        for b in (q, found, counts):
            b.release()
        return [f[i, : min(c[i], capacity)].astype(np.int64) if c[i] <= capacity else None for i in range(len(points))]

    def release(self) -> None:
        for b in (self.photons, self.keys, self.alt, self.start, self.table, self.map, self.kd):
            if b is not None:
                b.release()
        self.cells.release()
        self.sorter.release()
        for p in self._queries.values():
            p.release()
