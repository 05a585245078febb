"""GPU refit (compute) of the binary BVH for moving geometry, beside the numpy `Bvh.refit`.

Same triangles, new vertex positions: the tree's topology stays, its boxes are recomputed bottom-up
on the GPU (glsl/accel/refit.comp): one dispatch rewrites the triangle buffer's vertices, then one
dispatch per tree level, deepest first, rewrites the child boxes of that level's nodes. The result
equals `Bvh.refit` + `Bvh.pack_nodes()` bit for bit (tests/test_refit_gpu.py). The host `Bvh`'s own
boxes are not touched (its `vertices` are updated); `read_nodes()` reads the GPU's back.

A refit tree's quality decays as geometry moves away from where it was built (boxes overlap more);
rebuild when that matters. The wide layouts are refit on the host (`Bvh.refit` + `GpuBvh.update`).
"""
from __future__ import annotations

import numpy as np

from ..gl import shaders
from ..gl.glsl_constants import declare
from ..gl.gpu_layout import SSBO
from .bvh import _check_vertices
from .gpu import DEFAULT_BINDING, GpuBvh, _moderngl

_LOCAL_SIZE = declare("REFIT_LOCAL", 64)  # glsl/accel/refit.comp's local size
_MAX_GROUPS_X = 65535


class GpuRefit:
    """Refits `gpu_bvh` (binary layout) from new vertex positions on the GPU."""

    def __init__(self, ctx, gpu_bvh: GpuBvh, base_binding: int = DEFAULT_BINDING):
        if gpu_bvh.width != 2:
            raise ValueError(f"GPU refit works on the bvh2 layout, not {gpu_bvh.layout}; refit on the host "
                             f"(Bvh.refit + GpuBvh.update) or rebuild")
        self.ctx = _moderngl(ctx)
        self.gpu = gpu_bvh
        self.base = base_binding
        bvh = gpu_bvh.bvh
        defines = {"BVH_NODES_BINDING": base_binding, "BVH_TRIS_BINDING": base_binding + 1}
        self.programs = [shaders.compute(self.ctx, "accel/refit.comp", {**defines, "REFIT_STAGE": s}) for s in (0, 1)]
        self.slots = bvh.reference_count
        self.vertex_count = len(bvh.vertices)
        self.index = self.ctx.buffer(np.ascontiguousarray(bvh.indices, np.uint32).tobytes() or b"\0" * 4)
        # GPU node numbers (internal nodes in preorder) grouped by tree level, deepest first.
        internal = np.flatnonzero(bvh.left >= 0)
        if len(internal) == 0:    # a lone leaf: GPU node 0 holds it
            gpu_nodes, depth = np.zeros(1, np.int64), np.zeros(1, np.int64)
        else:
            gpu_nodes, depth = np.arange(len(internal)), bvh.depth[internal]
        order = np.argsort(-depth, kind="stable")
        levels = np.unique(depth)[::-1]
        counts = np.array([(depth == d).sum() for d in levels])
        self.levels = list(zip(np.concatenate([[0], np.cumsum(counts)[:-1]]).tolist(), counts.tolist()))
        self.level_nodes = self.ctx.buffer(gpu_nodes[order].astype(np.uint32).tobytes())
        self.vertices = self.ctx.buffer(reserve=max(1, self.vertex_count) * 16)

    def run(self, vertices) -> None:
        """Upload new positions (V,3) and refit the GPU buffers (no read-back)."""
        v = _check_vertices(vertices)
        if v.shape[0] != self.vertex_count:
            raise ValueError(f"refit needs {self.vertex_count} vertices, got {v.shape[0]}")
        self.gpu.bvh.vertices = v
        if self.slots == 0:
            return
        v4 = np.zeros((len(v), 4), np.float32)
        v4[:, :3] = v
        self.vertices.write(v4.tobytes())
        self.gpu.bind(self.base)
        self.vertices.bind_to_storage_buffer(SSBO["refit_vertices"])
        self.index.bind_to_storage_buffer(SSBO["refit_index"])
        self._dispatch(self.programs[0], self.slots, 0)
        self.ctx.memory_barrier()
        self.level_nodes.bind_to_storage_buffer(SSBO["refit_index"])
        for offset, count in self.levels:
            self._dispatch(self.programs[1], count, offset)
            self.ctx.memory_barrier()

    def _dispatch(self, prog, n: int, offset: int) -> None:
        groups = -(-n // _LOCAL_SIZE)
        gx = min(groups, _MAX_GROUPS_X)
        prog["count"].value = n
        if prog.get("offset", None) is not None:
            prog["offset"].value = offset
        prog.run(gx, -(-groups // gx), 1)

    def read_nodes(self) -> np.ndarray:
        """(gpu_node_count, 16) float32: the GPU's node buffer (compare with Bvh.pack_nodes())."""
        return np.frombuffer(self.gpu.nodes.read(), np.float32).reshape(-1, 16).copy()

    def read_triangles(self) -> np.ndarray:
        return np.frombuffer(self.gpu.triangles.read(), np.float32).reshape(-1, 12).copy()

    def release(self) -> None:
        for b in (self.index, self.level_nodes, self.vertices):
            b.release()


__all__ = ["GpuRefit"]
