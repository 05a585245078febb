"""Bounding volume hierarchy: binned-SAH build in numpy, GPU packing, refit, reference traversal.

Build
-----
Top-down binned SAH (Wald 2007), processed one *tree level at a time*: every node of a level is
binned, scanned and partitioned together with whole-array numpy operations, so the Python loop runs
once per level (18-23 levels for 16k-1.1M triangles), not once per node. Primitives are triangle bounding boxes binned by
centroid into `bins` slots per axis; per-bin boxes come from `np.minimum.at` (1-D, which numpy
runs fast), prefix/suffix boxes from `accumulate`. A node becomes a leaf when the SAH says so and it
holds at most `max_leaf_size` triangles; a node whose centroids all coincide is halved by position;
depth is capped at `max_depth` (the GPU stack size). Triangles are reordered so that every leaf is
one contiguous range; `prim_ids` maps a reordered slot back to the caller's triangle ID.

`build_bvh(..., spatial_splits=True)` is the SBVH (sbvh.py): nodes may also split at planes that cut
triangles, so a triangle may fill several slots (`reference_count` >= `triangle_count`), each holding
the whole triangle and its original ID; everything that reads leaves works on slots and is unchanged.

The binary tree is stored in depth-first preorder (`left`, `right`, `start`, `count`, boxes), which
is what the reference traversal walks and what `refit` updates.

GPU layout (see `pack_nodes`, `pack_triangles`)
----------------------------------------------
BVH2 with both child boxes stored in the parent ("child pair" nodes, Aila & Laine 2009), 64 bytes =
4 x vec4 per internal node:

    vec4 0: L.lo.x L.hi.x L.lo.y L.hi.y
    vec4 1: L.lo.z L.hi.z R.lo.x R.hi.x
    vec4 2: R.lo.y R.hi.y R.lo.z R.hi.z
    vec4 3: (int bits) L.index R.index L.count R.count

count == 0: the child is an internal node and index is its GPU node number; count > 0: the child is a
leaf of `count` triangles starting at reordered triangle `index`. An empty child has an inverted box
(lo > hi), which the octant-ordered slab test never enters. Root is GPU node 0. Boxes are widened by
one ulp when packed (`widen`), so axis-parallel rays lying in a box face still enter it.
Triangles: 48 bytes = 3 x vec4 per triangle, (v0.xyz, original id as uint bits), (v1.xyz, 0), (v2.xyz, 0),
raw vertices because the watertight test (Woop et al. 2013) works on them.

Why this layout: one node fetch (4 vec4 loads) tests two boxes, so a ray needs half the dependent
node fetches of a 32-byte one-box-per-node BVH2 for the same bytes. Measured with the reference
traversal's counters (`trace_reference(..., stats=)`) on Sponza (66k triangles): 73.3 vs 36.1 fetches
per primary ray from the atrium centre (2.34 vs 2.31 kB), 74.2 vs 36.6 for random rays. On the NVIDIA GPU
(EGL, `python -m rayvr.accel.gpu`, 2 x 1440 x 1600 rays) this traversal runs Sponza at 2.9 GRays/s for
coherent primary rays, 0.75 GRays/s for shadow rays to a point light, 0.19 GRays/s for random rays.
Wide BVHs collapsed from this tree (BVH4/BVH8 with quantized child boxes) are in wide.py; `rayvr
bench rays` measures them against this layout per ray kind.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..gl.glsl_constants import declare
from ..gl.gpu_layout import BVH_FACE_SLACK
from .sah import _binned_sah, _half_area, _leaf_or_split, _segment_positions
from .sbvh import build_sbvh
from ..render_options.bvh_build import BUILDS

EMPTY_LO = np.float32(3.0e38)   # inverted box for an empty child slot: lo > hi, never entered
EMPTY_HI = np.float32(-3.0e38)
NODE_BYTES = 64
SPLIT_ALPHA = 1e-5          # SBVH: try spatial splits where object children overlap > alpha x root area
MAX_DUPLICATION = 0.3       # SBVH: at most 30 % more triangle references than triangles
# SBVH: try spatial splits only in nodes of at least this many references. Clipping the references
# of every small node was most of the build; Sponza, built on the host: 1 ->
# 16.9 s, SAH cost 55.95; 64 -> 6.8 s, 56.92 (the SAH build: 69.05)
SPATIAL_MIN_REFS = 64
TRIANGLE_BYTES = 48
# Box tests admit boxes entered up to this factor beyond the closest hit so far (glsl/accel/bvh.glsl
# bvh_reach): a box's computed entry and a hit's computed distance each carry a few ulps, and a
# triangle lying in its box's face (a floor) is entered at its own hit distance, so without it the
# traversal order decided whether a closer hit was found (seen on the GPU: Sponza, an edge pixel of a
# tile-culled frame). 2^-16: ~128 ulps.
HIT_REACH = declare("BVH_HIT_REACH", 1.0 + 2.0 ** -16)
SAFE_INVERSE_TINY = declare("BVH_SAFE_INVERSE_TINY", 1e-20)  # safe_inverse (and bvh.glsl's): |d| below it is zero
# offset_ray (and glsl/accel/ray.glsl's): within OFFSET_ORIGIN_BAND of the origin a fixed distance
# OFFSET_FLOAT_SCALE along the normal, else OFFSET_INT_SCALE float ulps per unit normal.
OFFSET_ORIGIN_BAND = declare("OFFSET_ORIGIN_BAND", 1.0 / 32.0)
OFFSET_FLOAT_SCALE = declare("OFFSET_FLOAT_SCALE", 1.0 / 65536.0)
OFFSET_INT_SCALE = declare("OFFSET_INT_SCALE", 32.0)


class BufferTooLargeError(ValueError):
    """A GPU buffer of this scene is larger than the device allows for one shader storage block."""

    def __init__(self, buffer: str, size: int, limit: int):
        self.buffer, self.size, self.limit = buffer, int(size), int(limit)
        super().__init__(
            f"BVH buffer '{buffer}' needs {size:,} bytes ({size / 2**20:.1f} MiB) but this device allows "
            f"{limit:,} bytes ({limit / 2**20:.1f} MiB) per shader storage block "
            f"(GL_MAX_SHADER_STORAGE_BLOCK_SIZE); the scene is too big for this device")


@dataclass
class Bvh:
    """A binary BVH in depth-first preorder (node 0 is the root) over reordered triangles."""

    node_lo: np.ndarray     # (N,3) float32
    node_hi: np.ndarray     # (N,3) float32
    left: np.ndarray        # (N,) int32, -1 for a leaf
    right: np.ndarray       # (N,) int32, -1 for a leaf
    start: np.ndarray       # (N,) int32, first reordered triangle of a leaf
    count: np.ndarray       # (N,) int32, triangles in a leaf, 0 for internal nodes
    depth: np.ndarray       # (N,) int32
    prim_ids: np.ndarray    # (T,) uint32, original triangle ID of each reordered slot
    indices: np.ndarray     # (T,3) int64, vertex indices of the reordered triangles
    vertices: np.ndarray    # (V,3) float32, the current vertex positions
    build_seconds: float = 0.0
    params: dict = field(default_factory=dict)

    @property
    def triangle_count(self) -> int:
        """The caller's triangles (an SBVH holds more references: `reference_count`)."""
        return int(self.params.get("triangles", len(self.prim_ids)))

    @property
    def reference_count(self) -> int:
        """Leaf slots: one per triangle, more where spatial splits cut triangles (sbvh.py)."""
        return int(len(self.prim_ids))

    @property
    def node_count(self) -> int:
        return int(len(self.left))

    @property
    def max_depth(self) -> int:
        return int(self.depth.max()) if len(self.depth) else 0

    def triangles(self) -> np.ndarray:
        """(T,3,3) float32 vertices of the reordered triangles."""
        return self.vertices[self.indices]

    # ------------------------------------------------------------------ quality
    def sah_cost(self, traversal_cost: float = 1.0, triangle_cost: float = 1.0) -> float:
        """Expected cost of a random ray hitting the root: sum of area-weighted node and triangle tests."""
        if self.reference_count == 0:
            return 0.0
        area = _half_area(self.node_lo.astype(np.float64), self.node_hi.astype(np.float64))
        root = max(area[0], np.finfo(np.float64).tiny)
        internal = self.left >= 0
        return float((traversal_cost * area[internal].sum()
                      + triangle_cost * (area[~internal] * self.count[~internal]).sum()) / root)

    def stats(self) -> dict:
        leaves = self.left < 0
        return {
            "triangles": self.triangle_count,
            "references": self.reference_count,
            "build": "sbvh" if self.params.get("spatial_splits") else "sah",
            "nodes": self.node_count,
            "leaves": int(leaves.sum()),
            "gpu_nodes": self.gpu_node_count,
            "max_depth": self.max_depth,
            "mean_leaf_size": float(self.count[leaves].mean()) if leaves.any() else 0.0,
            "max_leaf_size": int(self.count.max()) if len(self.count) else 0,
            "sah_cost": self.sah_cost(),
            "build_seconds": self.build_seconds,
            "gpu_bytes": self.gpu_sizes(),
        }

    # ------------------------------------------------------------------ refit
    def refit(self, vertices) -> None:
        """New positions for the same vertices (same topology): recompute every box bottom-up."""
        vertices = _check_vertices(vertices)
        if vertices.shape != self.vertices.shape:
            raise ValueError(f"refit needs {self.vertices.shape[0]} vertices, got {vertices.shape[0]}")
        self.vertices = vertices
        if self.reference_count == 0:
            return
        tri = vertices[self.indices]
        tlo, thi = tri.min(axis=1), tri.max(axis=1)
        leaves = np.flatnonzero(self.left < 0)
        self.node_lo[leaves] = np.minimum.reduceat(tlo, self.start[leaves], axis=0)
        self.node_hi[leaves] = np.maximum.reduceat(thi, self.start[leaves], axis=0)
        internal = self.left >= 0
        for d in range(self.max_depth, -1, -1):   # children are one level deeper than parents
            n = np.flatnonzero(internal & (self.depth == d))
            if len(n):
                l, r = self.left[n], self.right[n]
                self.node_lo[n] = np.minimum(self.node_lo[l], self.node_lo[r])
                self.node_hi[n] = np.maximum(self.node_hi[l], self.node_hi[r])

    # ------------------------------------------------------------------ GPU layout
    @property
    def gpu_node_count(self) -> int:
        return max(1, int((self.left >= 0).sum()))

    def gpu_sizes(self) -> dict[str, int]:
        return {"bvh_nodes": self.gpu_node_count * NODE_BYTES,
                "bvh_triangles": max(1, self.reference_count) * TRIANGLE_BYTES}

    def check_fits(self, max_ssbo_bytes: int) -> None:
        """Raise BufferTooLargeError when a GPU buffer exceeds the device's storage-block limit."""
        if not max_ssbo_bytes:
            return
        for name, size in self.gpu_sizes().items():
            if size > max_ssbo_bytes:
                raise BufferTooLargeError(name, size, max_ssbo_bytes)

    def pack_nodes(self) -> np.ndarray:
        """(gpu_node_count, 16) float32 child-pair nodes (layout in the module docstring)."""
        internal = np.flatnonzero(self.left >= 0)
        if len(internal) == 0:  # a lone leaf (or empty scene): one node, leaf left, empty right
            out = np.zeros((1, 16), np.float32)
            _put_child(out, 0, self.node_lo[:1], self.node_hi[:1])
            _put_child(out, 1, np.full((1, 3), EMPTY_LO), np.full((1, 3), EMPTY_HI))
            out[:, 12:].view(np.int32)[:] = [[self.start[0], 0, self.count[0], 0]]
            return out
        gpu_index = np.full(self.node_count, -1, np.int64)
        gpu_index[internal] = np.arange(len(internal))
        out = np.zeros((len(internal), 16), np.float32)
        meta = out[:, 12:].view(np.int32)
        for side, child in enumerate((self.left[internal], self.right[internal])):
            _put_child(out, side, self.node_lo[child], self.node_hi[child])
            leaf = self.left[child] < 0
            meta[:, side] = np.where(leaf, self.start[child], gpu_index[child])
            meta[:, 2 + side] = np.where(leaf, self.count[child], 0)
        return out

    def pack_triangles(self) -> np.ndarray:
        """(T, 12) float32: v0.xyz + original id bits, v1.xyz, v2.xyz (one zero triangle if empty)."""
        out = np.zeros((max(1, self.reference_count), 12), np.float32)
        if self.reference_count:
            out.reshape(-1, 3, 4)[:, :, :3] = self.triangles()
            out[:, 3].view(np.uint32)[:] = self.prim_ids
        return out


FACE_SLACK = np.float32(BVH_FACE_SLACK)


def widen(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boxes grown by one float ulp on every side, and by at least FACE_SLACK, as traversal sees them.

    An axis-parallel ray lying exactly in a box face gets (face - origin) * inv = 0 * large = 0 for
    its far plane and would miss the box; slack makes the face strictly outside the ray. One ulp
    is not enough at a face at 0 (1.4e-45, a denormal a GPU may flush): hence the floor
    (gpu_layout.BVH_FACE_SLACK), whose product with glsl/accel/bvh.glsl's safe inverse of a zero
    component (1 / 1e-20) exceeds any distance in a scene.
    """
    lo, hi = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    return (np.minimum(np.nextafter(lo, np.float32(-np.inf)), lo - FACE_SLACK),
            np.maximum(np.nextafter(hi, np.float32(np.inf)), hi + FACE_SLACK))


def _put_child(out: np.ndarray, side: int, lo: np.ndarray, hi: np.ndarray) -> None:
    """Write child boxes (widened by an ulp) into the interleaved lo/hi slots of a child-pair node."""
    lo, hi = widen(lo, hi)
    base = 6 * side
    for axis in range(3):
        out[:, base + 2 * axis] = lo[:, axis]
        out[:, base + 2 * axis + 1] = hi[:, axis]


# ====================================================================== build

def _check_vertices(vertices) -> np.ndarray:
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {v.shape}")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise ValueError(f"vertices contain NaN or inf (first bad vertex: {int(np.flatnonzero(bad)[0])}, "
                         f"{int(bad.sum())} in all); the BVH needs finite positions")
    return v


def _check_indices(indices, n_vertices: int) -> np.ndarray:
    i = np.asarray(indices)
    if i.size == 0:
        return np.zeros((0, 3), np.int64)
    if i.ndim != 2 or i.shape[1] != 3 or not np.issubdtype(i.dtype, np.integer):
        raise ValueError(f"indices must be an integer array of shape (T, 3), got {i.dtype} {i.shape}")
    i = i.astype(np.int64)
    if i.min() < 0 or i.max() >= n_vertices:
        raise ValueError(f"indices must lie in [0, {n_vertices}); found {i.min()}..{i.max()}")
    return i


def build_bvh(vertices, indices, *, bins: int = 16, max_leaf_size: int = 8, max_depth: int = 64,
              traversal_cost: float = 1.0, triangle_cost: float = 1.0, spatial_splits: bool = False,
              split_alpha: float = SPLIT_ALPHA, max_duplication: float = MAX_DUPLICATION,
              spatial_min_refs: int = SPATIAL_MIN_REFS,
              progress: bool = False) -> Bvh:
    """Binned-SAH BVH over triangles `indices` (T,3) of `vertices` (V,3), in scene-local coordinates.

    `traversal_cost`/`triangle_cost` weigh a child-pair node test against a triangle test in the SAH.
    Degenerate (zero-area) triangles are kept: the intersection test never reports them.
    `spatial_splits`: the SBVH build (sbvh.py): spatial splits tried where an object split's children
    overlap by more than `split_alpha` x the root's area, in nodes of at least `spatial_min_refs`
    references, with at most `max_duplication` x T extra triangle references; `progress` shows its
    tqdm bar.
    """
    t0 = time.perf_counter()
    V = _check_vertices(vertices)
    I = _check_indices(indices, len(V))
    T = len(I)
    if not (np.isfinite(split_alpha) and split_alpha >= 0):
        raise ValueError(f"split_alpha must be a number >= 0, got {split_alpha!r}")
    if not (np.isfinite(max_duplication) and max_duplication >= 0):
        raise ValueError(f"max_duplication must be a number >= 0, got {max_duplication!r}")
    if not (isinstance(spatial_min_refs, (int, np.integer)) and spatial_min_refs >= 1):
        raise ValueError(f"spatial_min_refs must be an integer >= 1, got {spatial_min_refs!r}")
    params = dict(bins=bins, max_leaf_size=max_leaf_size, max_depth=max_depth,
                  traversal_cost=traversal_cost, triangle_cost=triangle_cost, triangles=T,
                  spatial_splits=bool(spatial_splits))
    if spatial_splits:
        params.update(split_alpha=float(split_alpha), max_duplication=float(max_duplication),
                      spatial_min_refs=int(spatial_min_refs))
    if T == 0:  # one empty leaf with an inverted box: every ray misses
        return Bvh(np.full((1, 3), EMPTY_LO), np.full((1, 3), EMPTY_HI), np.full(1, -1, np.int32),
                   np.full(1, -1, np.int32), np.zeros(1, np.int32), np.zeros(1, np.int32),
                   np.zeros(1, np.int32), np.zeros(0, np.uint32), I, V, time.perf_counter() - t0, params)

    if spatial_splits:
        levels, slots = build_sbvh(V, I, bins=bins, max_leaf_size=max_leaf_size, max_depth=max_depth,
                                   traversal_cost=traversal_cost, triangle_cost=triangle_cost, split_alpha=split_alpha,
                                   max_duplication=max_duplication, spatial_min_refs=int(spatial_min_refs),
                                   progress=progress, params=params)
        bvh = _finish(*levels, slots, I, V, params)
        bvh.build_seconds = time.perf_counter() - t0
        return bvh
    tri = V[I]
    tlo, thi = tri.min(axis=1), tri.max(axis=1)                 # float32, exact: boxes stay conservative
    cen = (tlo + thi) * np.float32(0.5)
    order = np.arange(T, dtype=np.int64)                        # reordered slot -> original triangle

    # Node records, appended a level at a time (ids of one level are contiguous).
    lo_list, hi_list = [tlo.min(axis=0, keepdims=True)], [thi.max(axis=0, keepdims=True)]
    start_list, count_list = [np.zeros(1, np.int64)], [np.array([T], np.int64)]
    left_list, right_list = [], []
    n_nodes = 1
    level_ids = np.array([0])                                   # node ids of the current level
    level_start, level_count = start_list[0], count_list[0]
    level_lo, level_hi = lo_list[0], hi_list[0]
    depth = 0
    B = int(bins)

    while len(level_ids):
        A = len(level_ids)
        pos, seg, _ = _segment_positions(level_start, level_count)
        prims = order[pos]
        # Candidate planes per node grow with its size: the per-(node, bin) work dominates the deep
        # levels, where nodes are many and small, and a 3-triangle node needs no 16 bins.
        nb = np.minimum(B, 2 ** np.ceil(np.log2(np.maximum(level_count, 2))).astype(np.int64))
        nb[(level_count <= 1) | (depth >= max_depth)] = 0      # leaves whatever the SAH says
        best_cost = np.full(A, np.inf)
        split_axis = np.zeros(A, np.int64)
        split_bin = np.zeros(A, np.int64)
        b = np.zeros((len(prims), 3), np.int64)
        for g in np.unique(nb[nb > 0]):
            nodes = np.flatnonzero(nb == g)
            in_g = (nb == g)[seg]
            local = np.full(A, -1, np.int64)
            local[nodes] = np.arange(len(nodes))
            p = prims[in_g]
            b[in_g], best_cost[nodes], split_axis[nodes], split_bin[nodes] = _binned_sah(
                cen[p], tlo[p], thi[p], local[seg[in_g]], level_count[nodes], int(g))
        make_leaf, halve = _leaf_or_split(best_cost, level_lo, level_hi, level_count, depth >= max_depth,
                                          max_leaf_size, traversal_cost, triangle_cost)

        left_ids = np.full(A, -1, np.int64)
        right_ids = np.full(A, -1, np.int64)
        split = np.flatnonzero(~make_leaf)
        if len(split) == 0:
            left_list.append(left_ids)
            right_list.append(right_ids)
            break

        # Partition each split node's range in place: left-side triangles first, order kept.
        in_split = ~make_leaf[seg]
        s_seg = seg[in_split]
        s_pos = pos[in_split]
        rank_in_node = s_pos - level_start[s_seg]
        go_right = np.where(halve[s_seg], rank_in_node >= level_count[s_seg] // 2,
                            b[in_split, split_axis[s_seg]] > split_bin[s_seg])
        go_left = ~go_right
        n_left = np.bincount(s_seg, weights=go_left, minlength=A).astype(np.int64)
        excl_l = np.cumsum(go_left) - go_left
        excl_r = np.cumsum(go_right) - go_right
        first = np.searchsorted(s_seg, s_seg)                   # index of each node's first element
        excl_l = excl_l - excl_l[first]
        excl_r = excl_r - excl_r[first]
        new_pos = level_start[s_seg] + np.where(go_left, excl_l, n_left[s_seg] + excl_r)
        order[new_pos] = order[s_pos].copy()

        # Children: two per split node, ids contiguous in this order: (L0, R0, L1, R1, ...).
        S = len(split)
        left_ids[split] = n_nodes + 2 * np.arange(S)
        right_ids[split] = left_ids[split] + 1
        left_list.append(left_ids)
        right_list.append(right_ids)
        c_start = np.empty(2 * S, np.int64)
        c_count = np.empty(2 * S, np.int64)
        c_start[0::2] = level_start[split]
        c_count[0::2] = n_left[split]
        c_start[1::2] = level_start[split] + n_left[split]
        c_count[1::2] = level_count[split] - n_left[split]
        cpos, _, coff = _segment_positions(c_start, c_count)
        cprims = order[cpos]
        level_lo = np.minimum.reduceat(tlo[cprims], coff, axis=0)
        level_hi = np.maximum.reduceat(thi[cprims], coff, axis=0)
        level_start, level_count = c_start, c_count
        level_ids = n_nodes + np.arange(2 * S)
        n_nodes += 2 * S
        lo_list.append(level_lo)
        hi_list.append(level_hi)
        start_list.append(c_start)
        count_list.append(c_count)
        depth += 1

    bvh = _finish(lo_list, hi_list, start_list, count_list, left_list, right_list, order, I, V, params)
    bvh.build_seconds = time.perf_counter() - t0
    return bvh


def _finish(lo_list, hi_list, start_list, count_list, left_list, right_list, slots, I, V, params) -> Bvh:
    """The Bvh from per-level node records (BFS ids, levels contiguous; a leaf's references are
    slots[start:start + count]), renumbered to depth-first preorder for locality, with the reference
    slots reordered so that leaves lie in preorder too (the identity for the in-place SAH build)."""
    lo = np.concatenate(lo_list).astype(np.float32)
    hi = np.concatenate(hi_list).astype(np.float32)
    start = np.concatenate(start_list)
    count = np.concatenate(count_list)
    left = np.concatenate(left_list)
    right = np.concatenate(right_list)
    level_sizes = [len(x) for x in start_list]
    depth_of = np.repeat(np.arange(len(level_sizes)), level_sizes)
    leaf = left < 0
    count = np.where(leaf, count, 0)
    pre = _preorder(left, right, level_sizes)
    inv = np.empty_like(pre)
    inv[pre] = np.arange(len(pre))
    leaves = inv[leaf[inv]]                                     # leaves in preorder
    pos, _, offsets = _segment_positions(start[leaves], count[leaves])
    slots = np.asarray(slots)[pos]
    start = start.copy()
    start[leaves] = offsets

    def remap(ids):
        return np.where(ids >= 0, pre[np.maximum(ids, 0)], -1)[inv].astype(np.int32)

    return Bvh(lo[inv], hi[inv], remap(left), remap(right), start[inv].astype(np.int32),
               count[inv].astype(np.int32), depth_of[inv].astype(np.int32),
               slots.astype(np.uint32), I[slots], V, 0.0, params)


def _preorder(left: np.ndarray, right: np.ndarray, level_sizes: list[int]) -> np.ndarray:
    """Depth-first preorder number of every node (BFS ids, levels contiguous), vectorized per level."""
    bounds = np.concatenate([[0], np.cumsum(level_sizes)])
    size = np.ones(len(left), np.int64)
    for d in range(len(level_sizes) - 1, -1, -1):               # subtree sizes, bottom-up
        n = np.arange(bounds[d], bounds[d + 1])
        n = n[left[n] >= 0]
        size[n] = 1 + size[left[n]] + size[right[n]]
    pre = np.zeros(len(left), np.int64)
    for d in range(len(level_sizes)):                           # numbers, top-down
        n = np.arange(bounds[d], bounds[d + 1])
        n = n[left[n] >= 0]
        pre[left[n]] = pre[n] + 1
        pre[right[n]] = pre[n] + 1 + size[left[n]]
    return pre


# ====================================================================== reference tracing

def safe_inverse(d: np.ndarray) -> np.ndarray:
    """1/d with zero (and tiny) components replaced by a large finite value of the same sign.

    A finite inverse keeps the slab test free of 0*inf = NaN for rays lying in a box plane; the same
    rule is used by the GLSL traversal.
    """
    sign = np.where(d < 0, -1.0, 1.0)
    return 1.0 / np.where(np.abs(d) < SAFE_INVERSE_TINY, sign * SAFE_INVERSE_TINY, d)


def valid_rays(d: np.ndarray, tmin: np.ndarray, tmax: np.ndarray) -> np.ndarray:
    """Rays worth tracing: finite, non-zero direction and a non-empty [tmin, tmax] interval."""
    return np.isfinite(d).all(axis=-1) & ((d * d).sum(axis=-1) > 0) & (tmax > tmin)


def intersect_triangles(o, d, v0, v1, v2, tmin, tmax):
    """Watertight ray-triangle test (Woop, Benthin & Wald 2013), float64, broadcasting.

    o, d: (..., 3) rays; v0, v1, v2: (..., 3) triangles. Returns (hit, t, u, v) where u, v weigh v1 and
    v2 (hit point = (1-u-v) v0 + u v1 + v v2, as Embree reports). No backface culling.
    """
    o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
    v0, v1, v2 = (np.asarray(x, np.float64) for x in (v0, v1, v2))
    # Axis of largest |d| becomes z; x, y follow cyclically and swap when d.z < 0 (keeps winding).
    kz = np.argmax(np.abs(d), axis=-1)
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    dz_at = np.take_along_axis(d, kz[..., None], -1)[..., 0]
    swap = dz_at < 0
    kx, ky = np.where(swap, ky, kx), np.where(swap, kx, ky)
    eye = np.eye(3)
    ex, ey, ez = eye[kx], eye[ky], eye[kz]                      # one-hot picks: exact in float

    def pick(a, e):
        return (a * e).sum(axis=-1)

    with np.errstate(divide="ignore", invalid="ignore"):
        sz = 1.0 / pick(d, ez)
        sx, sy = pick(d, ex) * sz, pick(d, ey) * sz
        A, Bv, C = v0 - o, v1 - o, v2 - o
        ax, ay, az = pick(A, ex) - sx * pick(A, ez), pick(A, ey) - sy * pick(A, ez), sz * pick(A, ez)
        bx, by, bz = pick(Bv, ex) - sx * pick(Bv, ez), pick(Bv, ey) - sy * pick(Bv, ez), sz * pick(Bv, ez)
        cx, cy, cz = pick(C, ex) - sx * pick(C, ez), pick(C, ey) - sy * pick(C, ez), sz * pick(C, ez)
        U = cx * by - cy * bx                                   # weight of v0
        Vw = ax * cy - ay * cx                                  # weight of v1
        W = bx * ay - by * ax                                   # weight of v2
        inside = ~(((U < 0) | (Vw < 0) | (W < 0)) & ((U > 0) | (Vw > 0) | (W > 0)))
        det = U + Vw + W
        t = (U * az + Vw * bz + W * cz) / det
        hit = inside & (det != 0) & (t > tmin) & (t < tmax)
        return hit, np.where(hit, t, np.inf), Vw / det, W / det


def _prepare_rays(origins, directions, tmin, tmax):
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    n = len(o)
    tmin = np.broadcast_to(np.asarray(tmin, np.float64), (n,)).copy()
    tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,)).copy()
    ok = valid_rays(d, tmin, tmax)
    d = np.where(ok[:, None], d, 1.0)                           # keep arithmetic quiet; masked below
    return o, d, tmin, tmax, ok


def trace_reference(bvh: Bvh, origins, directions, tmin=0.0, tmax=np.inf, any_hit: bool = False,
                    stats: dict | None = None):
    """Slow, exact-ish reference: walks the binary tree for all rays at once (float64).

    Returns (prim, t, u, v): original triangle id (0xFFFFFFFF = miss), distance (inf on miss) and
    barycentrics; with any_hit=True returns a bool array (occluded). `stats`, when given, receives
    per-ray node fetches of a one-box-per-node BVH2 (`node_visits`: every popped node), of the
    child-pair layout (`pair_node_visits`: internal nodes whose box the ray enters) and the
    ray-triangle tests (`triangle_tests`: slots of every leaf entered).
    """
    w = RayWalk(bvh, origins, directions, tmin, tmax, any_hit, bvh.max_depth + 2)
    w.push(np.flatnonzero(w.ok), np.zeros(int(w.ok.sum()), np.int64))   # the root, for valid rays
    pair_visits = np.zeros(w.n, np.int64)
    while True:
        active, node = w.pop()
        if len(active) == 0:
            break
        hit_box = _slab(w.o[active], w.inv[active], bvh.node_lo[node], bvh.node_hi[node], w.tmin[active],
                        w.tbest[active])
        r, node = active[hit_box], node[hit_box]
        pair_visits[r] += bvh.left[node] >= 0
        is_leaf = bvh.left[node] < 0
        ln = node[is_leaf]
        w.leaf(r[is_leaf], bvh.start[ln], bvh.count[ln])
        ir, inode = r[~is_leaf], node[~is_leaf]
        w.push(ir, bvh.right[inode])
        w.push(ir, bvh.left[inode])
    if stats is not None:
        stats["node_visits"] = w.visits
        stats["pair_node_visits"] = pair_visits
        stats["triangle_tests"] = w.tests
    return w.result()


class RayWalk:
    """State of a numpy reference traversal of many rays at once (float64): per-ray stacks of node
    numbers, the closest hit so far, occlusion. Each layout's reference walk (binary here, wide in
    wide.py) pops nodes, tests its boxes and calls `leaf` and `push`. (Tile-culled traversal has no
    numpy walk: tests compare it with per-ray GPU traversal and this reference.)"""

    def __init__(self, bvh: Bvh, origins, directions, tmin, tmax, any_hit: bool, stack_size: int):
        self.bvh, self.any_hit = bvh, any_hit
        self.o, self.d, self.tmin, self.tbest, self.ok = _prepare_rays(origins, directions, tmin, tmax)
        self.n = n = len(self.o)
        self.inv = safe_inverse(self.d)
        self.prim = np.full(n, -1, np.int64)
        self.u, self.v = np.zeros(n), np.zeros(n)
        self.occluded = np.zeros(n, bool)
        self.stack = np.zeros((n, stack_size), np.int64)
        self.sp = np.zeros(n, np.int64)
        self.visits = np.zeros(n, np.int64)
        self.tests = np.zeros(n, np.int64)   # ray-triangle tests (leaf slots), per ray
        self.tris = bvh.triangles().astype(np.float64)

    def push(self, rays, nodes) -> None:
        self.stack[rays, self.sp[rays]] = nodes
        self.sp[rays] += 1

    def pop(self):
        """(rays, node each popped): every ray with a non-empty stack (an occluded any-hit ray stops)."""
        if self.any_hit:
            self.sp[self.occluded] = 0
        active = np.flatnonzero(self.sp > 0)
        self.sp[active] -= 1
        self.visits[active] += 1
        return active, self.stack[active, self.sp[active]]

    def leaf(self, rays, first, count) -> None:
        """Rays against their leaf ranges [first, first + count), keeping the closest hit (at equal
        t the lower triangle ID, as the GLSL leaf test: the order the walk meets them in does not
        decide)."""
        np.add.at(self.tests, rays, count)
        for k in range(int(count.max()) if len(count) else 0):
            m = k < count
            rr, slot = rays[m], first[m] + k
            found = self.prim[rr] >= 0
            bound = np.where(found, np.nextafter(self.tbest[rr], np.inf), self.tbest[rr])
            h, t, uu, vv = intersect_triangles(self.o[rr], self.d[rr], self.tris[slot, 0], self.tris[slot, 1],
                                               self.tris[slot, 2], self.tmin[rr], bound)
            h &= (t < self.tbest[rr]) | (self.bvh.prim_ids[slot].astype(np.int64) < np.where(found, self.prim[rr], 1 << 40))
            rr, slot = rr[h], slot[h]
            self.tbest[rr], self.u[rr], self.v[rr] = t[h], uu[h], vv[h]
            self.prim[rr] = self.bvh.prim_ids[slot]
            self.occluded[rr] = True

    def result(self):
        """Occlusion (any hit), or (prim, t, u, v) with 0xFFFFFFFF / inf on a miss."""
        if self.any_hit:
            return self.occluded
        miss = self.prim < 0
        return (np.where(miss, 0xFFFFFFFF, self.prim).astype(np.uint32), np.where(miss, np.inf, self.tbest),
                self.u, self.v)


def _slab(o, inv, lo, hi, tmin, tmax, widened: bool = False):
    """Ray-box overlap with near/far planes picked by the sign of the inverse direction; boxes are
    widened by an ulp first unless `widened` says they already contain that ulp (quantized boxes)."""
    lo, hi = (x.astype(np.float64) for x in ((lo, hi) if widened else widen(lo, hi)))
    pos = inv >= 0
    near = (np.where(pos, lo, hi) - o) * inv
    far = (np.where(pos, hi, lo) - o) * inv
    return np.maximum(near.max(axis=1), tmin) <= np.minimum(far.min(axis=1), tmax)


def trace_brute_force(vertices, indices, origins, directions, tmin=0.0, tmax=np.inf, any_hit=False,
                      chunk: int = 256):
    """Every ray against every triangle (float64): the reference for the reference."""
    tri = _check_vertices(vertices)[_check_indices(indices, len(vertices))].astype(np.float64)
    o, d, tmin, tmax, ok = _prepare_rays(origins, directions, tmin, tmax)
    n = len(o)
    prim = np.full(n, 0xFFFFFFFF, np.uint32)
    tt, u, v = np.full(n, np.inf), np.zeros(n), np.zeros(n)
    if len(tri) == 0:
        return np.zeros(n, bool) if any_hit else (prim, tt, u, v)
    for s in range(0, n, chunk):
        sl = slice(s, min(n, s + chunk))
        h, t, uu, vv = intersect_triangles(o[sl, None], d[sl, None], tri[None, :, 0], tri[None, :, 1],
                                           tri[None, :, 2], tmin[sl, None], tmax[sl, None])
        h &= ok[sl, None]
        t = np.where(h, t, np.inf)
        best = t.argmin(axis=1)
        rows = np.arange(len(best))
        hit = h[rows, best]
        prim[sl] = np.where(hit, best, 0xFFFFFFFF)
        tt[sl] = t[rows, best]
        u[sl], v[sl] = np.where(hit, uu[rows, best], 0), np.where(hit, vv[rows, best], 0)
    return np.isfinite(tt) if any_hit else (prim, tt, u, v)


def offset_ray(p, n):
    """Move p off its surface along n (Wächter & Binder, Ray Tracing Gems ch. 6), float32.

    Far from the origin the offset is a fixed number of float ulps (scale-invariant); near the origin,
    where ulps get tiny, a small fixed distance. The GLSL `offset_ray` does the same; its comment says
    why the integer step is 32 ulps per unit normal rather than the paper's 256.
    """
    p = np.asarray(p, np.float32)
    n = np.asarray(n, np.float32)
    of_i = (OFFSET_INT_SCALE * n).astype(np.int32)
    pi = p.view(np.int32)
    p_i = (pi + np.where(p < 0, -of_i, of_i)).astype(np.int32).view(np.float32)
    return np.where(np.abs(p) < OFFSET_ORIGIN_BAND, p + OFFSET_FLOAT_SCALE * n, p_i).astype(np.float32)
