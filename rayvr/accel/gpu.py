"""The BVH on the GPU: buffer upload (`GpuBvh`) and a batch ray tracer for tests and benchmarks.

A shader that traces rays `#include`s "accel/bvh.glsl" (from a file under glsl/, with the path relative
to it), builds with `gpu_bvh.defines(base)` among its defines, and calls `gpu_bvh.bind(base)` before
dispatching: node buffer at binding `base`, triangle buffer at `base + 1` (default base 8, clear of the
scene buffers 0..2 of glsl/common/scene.glsl).

Node layouts (`gpu_layout.BVH_LAYOUTS`): `bvh2`, the binary child-pair nodes of bvh.py (the
reference), `bvh4` / `bvh8`, wide nodes with quantized child boxes collapsed from it (wide.py), and
`cwbvh`, the compressed 8-wide BVH of Ylitie et al. 2017 (cwbvh.py; its node buffer holds copies of
its leaves' triangles, each naming its binary slot). All bind the binary triangle buffer and report
its triangle slots and IDs.
"""
from __future__ import annotations

from typing import NamedTuple

import moderngl
import numpy as np

from ..gl import shaders
from ..gl.glsl_constants import declare
from ..gl.gpu_layout import BVH_LAYOUTS, COMPRESSED_LAYOUT, SSBO, TILE_ENTRIES, TILE_RAYS
from ..gl.timing import time_gpu
from .bvh import Bvh, BufferTooLargeError
from .cwbvh import CwBvh, build_cwbvh, pack as pack_cwbvh
from .wide import WideBvh, build_wide, node_words, pack as pack_wide
from ..render_options.traversal import RAY_KINDS, DEFAULT_TRAVERSAL, parse_traversal, check_layout
# declare constants the tile-culled trace shaders read (TILE_SLACK, TILE_MIN_COS; CAMERA_*; SHARED_CHANNEL)
from . import frustum  # noqa: F401
from ..frame import graph  # noqa: F401
from ..frame.cameras import base as camera_models  # noqa: F401

DEFAULT_BINDING = SSBO["bvh_nodes"]  # nodes here, triangles at +1 (gpu_layout.SSBO)
STACK_SIZE = declare("BVH_BINARY_STACK_SIZE", 64)  # bvh.glsl's default BVH_STACK_SIZE (>= the build's max_depth)
# A wide traversal keeps one (node << 8 | child mask) entry a level: its stack per width (checked
# against the tree's depth, wide.group_stack_bound).
WIDE_STACK_SIZES = {4: 32, 8: 32}
WIDE_MAX_NODES = 1 << 24   # a stack entry holds the node index in 24 bits
# The compressed layout's stack: (group base, mask) pairs, one a level (two ints each in bvh_stack).
CWBVH_STACK_ENTRIES = 32
MISS = declare("BVH_MISS", 0xFFFFFFFF, uint=True)
MODES = {"closest": 0, "any": 1, "reflect": 2, "through": 3}
_LOCAL_SIZE = declare("TRACE_RAYS_LOCAL", 64)  # glsl/accel/trace_rays.comp's local size
TIMED_BATCHES = 5  # time_trace: median of this many timed batches of `repeats` dispatches
WARMUP_S = 1.0   # time_trace dispatches at least this long, until times settle (0.2 s left the first kind of rays measured 3.6x slow in some runs)
_MAX_GROUPS_X = 65535


def _moderngl(ctx) -> moderngl.Context:
    return getattr(ctx, "ctx", ctx)   # accept rayvr.gl.context.GLContext or a bare moderngl context


def max_ssbo_bytes(ctx) -> int:
    return int(_moderngl(ctx).info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or 0)


def layout_defines(base_binding: int = DEFAULT_BINDING, layout: str = "bvh2", ordered: bool = True) -> dict:
    """Defines that compile glsl/accel/bvh.glsl for `layout` (nodes at `base_binding`, triangles at +1).
    `ordered`: wide layouts visit a closest-hit ray's children nearest first (binary always does)."""
    width = check_layout(layout)
    d = {"BVH_NODES_BINDING": base_binding, "BVH_TRIS_BINDING": base_binding + 1,
         "BVH_STACK_SIZE": WIDE_STACK_SIZES.get(width, STACK_SIZE), "BVH_WIDTH": width}
    if layout == COMPRESSED_LAYOUT:   # octant order, no nearest-first: `ordered` does not apply
        d.update(BVH_COMPRESSED=1, BVH_STACK_SIZE=2 * CWBVH_STACK_ENTRIES)
    elif width > 2:
        d.update(BVH_NODE_VEC4=node_words(width) // 4, BVH_ORDERED=int(ordered))
    return d


class GpuBvh:
    """The packed BVH in two shader storage buffers (layouts: bvh.py and wide.py docstrings)."""

    def __init__(self, ctx, bvh: Bvh, limit: int | None = None, layout: str = "bvh2"):
        """`limit`: bytes per storage block; default: the device's GL_MAX_SHADER_STORAGE_BLOCK_SIZE.
        `layout`: bvh2 (binary, the reference), bvh4 or bvh8 (wide, collapsed from `bvh`), cwbvh
        (compressed 8-wide, collapsed from `bvh`)."""
        self.ctx = _moderngl(ctx)
        self.bvh = bvh
        self.layout = layout
        self.width = check_layout(layout)
        self.limit = max_ssbo_bytes(self.ctx) if limit is None else int(limit)
        bvh.check_fits(self.limit)
        if bvh.max_depth > STACK_SIZE:
            raise ValueError(f"BVH depth {bvh.max_depth} exceeds the GPU traversal stack ({STACK_SIZE}); "
                             f"build with max_depth <= {STACK_SIZE}")
        self.wide: WideBvh | CwBvh | None = None
        if self.width > 2:
            compressed = layout == COMPRESSED_LAYOUT
            self.wide = build_cwbvh(bvh) if compressed else build_wide(bvh, self.width)
            entries = CWBVH_STACK_ENTRIES if compressed else WIDE_STACK_SIZES[self.width]
            if self.wide.group_stack_bound > entries:
                raise ValueError(f"{layout}: a traversal may hold {self.wide.group_stack_bound} stack entries, "
                                 f"more than the GPU stack ({entries}); use bvh2")
            if not compressed and self.wide.node_count > WIDE_MAX_NODES:  # cwbvh's stack holds whole indices
                raise ValueError(f"{layout}: {self.wide.node_count} nodes, more than the traversal stack "
                                 f"addresses ({WIDE_MAX_NODES}); use bvh2")
            if self.limit and self.wide.nbytes > self.limit:
                raise BufferTooLargeError("bvh_nodes", self.wide.nbytes, self.limit)
        self.nodes = self.ctx.buffer(self._pack_nodes().tobytes())
        self.triangles = self.ctx.buffer(bvh.pack_triangles().tobytes())

    def _pack_nodes(self) -> np.ndarray:
        if self.wide is None:
            return self.bvh.pack_nodes()
        if isinstance(self.wide, CwBvh):
            self.wide.packed = pack_cwbvh(self.wide)   # same tree, boxes from the current vertices
            return self.wide.packed
        self.wide.packed = pack_wide(self.bvh, self.wide.child)   # same children, new boxes
        return self.wide.packed

    def update(self) -> None:
        """Re-upload boxes and vertices after `bvh.refit(...)` (same topology, same sizes)."""
        self.nodes.write(self._pack_nodes().tobytes())
        self.triangles.write(self.bvh.pack_triangles().tobytes())

    def bind(self, base_binding: int = DEFAULT_BINDING) -> None:
        self.nodes.bind_to_storage_buffer(base_binding)
        self.triangles.bind_to_storage_buffer(base_binding + 1)

    @staticmethod
    def defines(base_binding: int = DEFAULT_BINDING) -> dict:
        """Defines of the binary layout (the passes' default); `layout_defines` for the others."""
        return layout_defines(base_binding)

    def own_defines(self, base_binding: int = DEFAULT_BINDING, ordered: bool = True) -> dict:
        """Defines for this buffer's layout."""
        return layout_defines(base_binding, self.layout, ordered)

    @property
    def nbytes(self) -> int:
        return self.nodes.size + self.triangles.size

    def release(self) -> None:
        self.nodes.release()
        self.triangles.release()


class Hits(NamedTuple):
    prim: np.ndarray   # (N,) uint32 original triangle ID, 0xFFFFFFFF = miss
    t: np.ndarray      # (N,) float32, inf on a miss
    u: np.ndarray      # (N,) float32 barycentric weight of v1
    v: np.ndarray      # (N,) float32 barycentric weight of v2


def pack_rays(origins, directions, tmin=0.0, tmax=np.inf) -> np.ndarray:
    """(N, 8) float32: origin, tmin, direction, tmax (the layout trace_rays.comp reads)."""
    o = np.asarray(origins, np.float32).reshape(-1, 3)
    d = np.asarray(directions, np.float32).reshape(-1, 3)
    n = len(o)
    if d.shape != o.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} differ")
    rays = np.empty((n, 8), np.float32)
    rays[:, 0:3], rays[:, 4:7] = o, d
    rays[:, 3] = np.broadcast_to(np.asarray(tmin, np.float32), (n,))
    rays[:, 7] = np.broadcast_to(np.asarray(tmax, np.float32), (n,))
    return rays


class RayTracer:
    """Traces ray batches through glsl/accel/trace_rays.comp; one program per mode, built lazily.

    `tiles=True` (binary layout only) culls first: every TILE_RAYS consecutive rays form a tile whose
    frustum picks its entry nodes (accel/frustum.py, glsl/accel/tile_cull.comp); its rays are traced
    from those. Order the rays so that a tile's rays are coherent (frustum.tile_order)."""

    def __init__(self, ctx, gpu_bvh: GpuBvh, base_binding: int = DEFAULT_BINDING, ordered: bool = True,
                 tile_entries: int = TILE_ENTRIES, tile_sort: bool = True):
        """`ordered`: wide layouts visit closest-hit children nearest first (see layout_defines);
        `tile_entries`: the most entry nodes a tile's list holds (tiles=True); `tile_sort`: a tile's
        entries front to back along its central direction (False: tree order, to measure the gain)."""
        self.ctx = _moderngl(ctx)
        self.gpu_bvh = gpu_bvh
        self.base = base_binding
        self.ordered = ordered
        self.tile_entries = int(tile_entries)
        self.tile_sort = bool(tile_sort)
        self._programs: dict[tuple, moderngl.ComputeShader] = {}

    def tile_defines(self) -> dict:
        return {"TILE_RAYS": TILE_RAYS, "TILE_ENTRIES": self.tile_entries, "TILE_SORT": int(self.tile_sort),
                "TILE_ENTRIES_BINDING": SSBO["tile_entries"], "TILE_PLANES_BINDING": SSBO["tile_planes"]}

    def program(self, mode: str, offset: bool = True, tiles: bool = False, work: bool = False) -> moderngl.ComputeShader:
        key = (mode, offset, tiles, work)
        if key not in self._programs:
            if mode not in MODES:
                raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
            counted = self.gpu_bvh.width == 2 or self.gpu_bvh.layout == COMPRESSED_LAYOUT
            if (tiles and self.gpu_bvh.width != 2) or (work and not counted):
                what = "tile frustum culling walks the bvh2 layout" if tiles else \
                    "work counts count the bvh2 and cwbvh layouts"
                raise ValueError(f"{what}, not {self.gpu_bvh.layout}")
            defines = dict(self.gpu_bvh.own_defines(self.base, self.ordered), TRACE_MODE=MODES[mode],
                           OFFSET_RAYS=int(offset), RAYS_BINDING=self.base + 2, HITS_BINDING=self.base + 3,
                           **(self.tile_defines() if tiles else {}),
                           **({"BVH_COUNT_WORK": 1, "WORK_BINDING": self.base + 4} if work else {}))
            self._programs[key] = shaders.compute(self.ctx, "accel/trace_rays.comp", defines)
        return self._programs[key]

    def cull_program(self) -> moderngl.ComputeShader:
        key = ("cull",)
        if key not in self._programs:
            self._programs[key] = shaders.compute(self.ctx, "accel/tile_cull.comp", dict(
                self.gpu_bvh.own_defines(self.base), RAYS_BINDING=self.base + 2, **self.tile_defines()))
        return self._programs[key]

    def _tile_buffers(self, n: int):
        tiles = -(-n // TILE_RAYS)
        return (self.ctx.buffer(reserve=max(1, tiles) * (self.tile_entries + 1) * 4),
                self.ctx.buffer(reserve=max(1, tiles) * 5 * 16))

    def trace(self, origins, directions, tmin=0.0, tmax=np.inf, mode: str = "closest",
              offset: bool = True, tiles: bool = False, tile_info: dict | None = None, work: dict | None = None):
        """Trace rays; returns Hits, or for mode='any' a bool array (occluded). With `tiles`, the
        culled traversal; `tile_info` then receives each tile's entry list and frustum planes.
        `work` (bvh2 and cwbvh layouts): receives each ray's traversal work, counted on the GPU (bvh.glsl
        BVH_COUNT_WORK): `node_visits` (nodes fetched by walks), `entry_tests` (tile entry boxes
        tested), `triangle_tests`."""
        rays = pack_rays(origins, directions, tmin, tmax)
        n = len(rays)
        out = np.zeros((n, 4), np.uint32)
        limit = self.gpu_bvh.limit or 2**31
        chunk = max(TILE_RAYS, min(n, limit // rays.itemsize // 8, 1 << 24) // TILE_RAYS * TILE_RAYS)
        prog = self.program(mode, offset, tiles, work is not None)
        self.gpu_bvh.bind(self.base)
        infos, counts = [], []
        for s in range(0, n, chunk):
            part = rays[s:s + chunk]
            bufs = [self.ctx.buffer(part.tobytes()), self.ctx.buffer(reserve=len(part) * 16)]
            try:
                bufs[0].bind_to_storage_buffer(self.base + 2)
                bufs[1].bind_to_storage_buffer(self.base + 3)
                if work is not None:
                    bufs.append(self.ctx.buffer(reserve=len(part) * 16))
                    bufs[-1].bind_to_storage_buffer(self.base + 4)
                if tiles:
                    bufs += self._tile_buffers(len(part))
                    self._cull(bufs[-2], bufs[-1], len(part))
                self._dispatch(prog, len(part))
                out[s:s + len(part)] = np.frombuffer(bufs[1].read(), np.uint32).reshape(-1, 4)
                if work is not None:
                    counts.append(np.frombuffer(bufs[2].read(), np.uint32).reshape(-1, 4)[:, :3])
                if tiles:
                    infos.append((np.frombuffer(bufs[-2].read(), np.uint32).reshape(-1, self.tile_entries + 1),
                                  np.frombuffer(bufs[-1].read(), np.float32).reshape(-1, 5, 4)))
            finally:
                for b in bufs:
                    b.release()
        if tile_info is not None and infos:
            lists = np.concatenate([i[0] for i in infos])
            tile_info.update(counts=lists[:, 0].astype(np.int64), entries=lists[:, 1:],
                             planes=np.concatenate([i[1] for i in infos]))
        if work is not None:
            c = np.concatenate(counts).astype(np.int64)
            work.update(node_visits=c[:, 0], entry_tests=c[:, 1], triangle_tests=c[:, 2])
        if mode == "any":
            return out[:, 0] != 0
        prim = out[:, 0].copy()
        t = out[:, 1].view(np.float32).copy()
        t[prim == MISS] = np.inf
        return Hits(prim, t, out[:, 2].view(np.float32).copy(), out[:, 3].view(np.float32).copy())

    def _cull(self, entries, planes, n: int) -> None:
        """Tile entry lists of the rays bound at base + 2 (one work group a tile)."""
        entries.bind_to_storage_buffer(SSBO["tile_entries"])
        planes.bind_to_storage_buffer(SSBO["tile_planes"])
        prog = self.cull_program()
        tiles = -(-n // TILE_RAYS)
        gx = min(tiles, _MAX_GROUPS_X)
        prog["ray_count"].value = n
        prog.run(gx, -(-tiles // gx), 1)
        self.ctx.memory_barrier()

    def _dispatch(self, prog: moderngl.ComputeShader, n: int) -> None:
        groups = -(-n // _LOCAL_SIZE)
        gx = min(groups, _MAX_GROUPS_X)
        gy = -(-groups // gx)
        prog["ray_count"].value = n
        prog.run(gx, gy, 1)

    def time_trace(self, origins, directions, tmin=0.0, tmax=np.inf, mode: str = "closest",
                   repeats: int = 10, tiles: bool = False) -> dict:
        """Rays already on the GPU, `repeats` dispatches: GPU ms per dispatch (timer query) and rays/s,
        after a warm-up until times settle. With `tiles`, a dispatch is the culling plus the trace
        (`cull_ms`: the culling alone)."""
        rays = pack_rays(origins, directions, tmin, tmax)
        n = len(rays)
        prog = self.program(mode, tiles=tiles)
        bufs = [self.ctx.buffer(rays.tobytes()), self.ctx.buffer(reserve=n * 16)]
        if tiles:
            bufs += self._tile_buffers(n)
        try:
            self.gpu_bvh.bind(self.base)
            bufs[0].bind_to_storage_buffer(self.base + 2)
            bufs[1].bind_to_storage_buffer(self.base + 3)

            def one():
                if tiles:
                    self._cull(bufs[2], bufs[3], n)
                self._dispatch(prog, n)

            t = time_gpu(self.ctx, one, repeats=repeats, min_seconds=WARMUP_S, batches=TIMED_BATCHES)
            cull = (time_gpu(self.ctx, lambda: self._cull(bufs[2], bufs[3], n), repeats=repeats,
                             min_seconds=0.2, batches=TIMED_BATCHES)["ms"] if tiles else 0.0)
        finally:
            for b in bufs:
                b.release()
        # llvmpipe reports ~0 for compute in timer queries: then `ms` is the wall time
        return {"rays": n, "gpu_ms": t["gpu_ms"], "gpu_ms_min": t["gpu_ms_min"], "gpu_ms_max": t["gpu_ms_max"],
                "wall_ms": t["wall_ms"], "rays_per_s": n / (t["ms"] * 1e-3), "cull_ms": cull}


def trace_rays(ctx, bvh_or_gpu, origins, directions, tmin=0.0, tmax=np.inf, mode: str = "closest"):
    """One-shot helper: upload (if given a Bvh), trace, return Hits (or occlusion for mode='any')."""
    owned = not isinstance(bvh_or_gpu, GpuBvh)
    gpu_bvh = GpuBvh(ctx, bvh_or_gpu) if owned else bvh_or_gpu
    try:
        return RayTracer(ctx, gpu_bvh).trace(origins, directions, tmin, tmax, mode)
    finally:
        if owned:
            gpu_bvh.release()


__all__ = ["GpuBvh", "layout_defines", "check_layout", "parse_traversal", "RAY_KINDS", "DEFAULT_TRAVERSAL", "RayTracer", "Hits", "trace_rays", "pack_rays", "max_ssbo_bytes",
           "BufferTooLargeError", "MISS", "MODES", "DEFAULT_BINDING", "STACK_SIZE"]
