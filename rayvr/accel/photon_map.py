"""Photon maps, host side: the hash grid's shape and the numpy reference of every GPU step.

The photon map of the `photon` effect (photon-mapping paper §3.1) is a **hash grid**: cells of the
search radius r over the scene's bounds with one empty cell of padding on each side, cell index
z * nx * ny + y * nx + x (paper eq. 2), photons sorted by cell, `start[c]` = prefix sum of the
counts (cell c holds photons start[c] .. start[c + 1]), and a query visits the 3x3x3 cells around
the point as 9 runs of 3 cells that are contiguous in x. The GPU builds it per frame
(frame/effects/photon/cells.py, scan.py, sort.py); the functions here are the slow paths
that the tests hold it to:

  grid_cells / build_grid       cell per photon, counts, start indices, stable order by cell
  grid_query / brute_query      photons within r of points: through the grid, or all pairs
  build_kdtree / kdtree_query   the paper's baseline: a balanced kd-tree in one array, built here
                                (the GPU only searches it: glsl/photon/kdtree.glsl)
  density                       the radiance estimate over all photons within r (no heap) or the
                                k nearest (heap, radius = distance of the k-th)

Photon records (glsl/photon/photon.glsl) are 8 words: position xyz, the surface normal packed
(snorm 16x2 octahedral), power rgb, and a word that is the split axis in the kd-tree's array.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gl.glsl_constants import declare

PHOTON_WORDS = 8
PHOTON_BYTES = 4 * PHOTON_WORDS
MAX_CELLS = 1 << 22  # grid cells at most: a smaller radius widens the cells (still >= r: exact)
ESTIMATORS = ("grid", "grid_heap", "kdtree", "kdtree_heap")  # the `estimator` parameter's values
for _index, _estimator in enumerate(ESTIMATORS):  # the shaders' PHOTON_ESTIMATOR_<NAME> (glsl/photon/estimate.glsl)
    declare(f"PHOTON_ESTIMATOR_{_estimator.upper()}", _index)
declare("PHOTON_ESTIMATOR_COUNT", len(ESTIMATORS))
MAX_K = declare("PHOTON_MAX_K", 64)  # the heap's size in the shaders


@dataclass(frozen=True)
class GridShape:
    """Cells of side `cell` from `origin` (scene-local), `dims` cells per axis (padding included)."""

    origin: tuple
    cell: float
    dims: tuple

    @property
    def cells(self) -> int:
        return int(self.dims[0] * self.dims[1] * self.dims[2])

    @property
    def dead(self) -> int:
        """The key of an empty photon slot: one past the last cell, so it sorts last."""
        return self.cells

    @property
    def key_bits(self) -> int:
        return max(1, int(self.dead).bit_length())


def grid_shape(lo, hi, radius: float, max_cells: int = MAX_CELLS) -> GridShape:
    """The grid over bounds [lo, hi] for search radius `radius`: cell = r (widened until the grid
    has at most `max_cells` cells), one empty cell of padding on each side so that the 3x3x3
    neighbourhood of any point inside never leaves the grid."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    size = np.maximum(hi - lo, 1e-6)
    cell = max(float(radius), 1e-9)
    while True:
        dims = np.ceil(size / cell).astype(np.int64) + 3  # +1: the top face; +2: the padding
        if int(np.prod(dims)) <= max_cells:
            break
        cell *= 1.25
    origin = lo - cell
    return GridShape(tuple(float(x) for x in origin), float(cell), tuple(int(d) for d in dims))


def grid_cells(shape: GridShape, positions: np.ndarray, valid=None) -> np.ndarray:
    """Cell index per photon (paper eq. 2), `shape.dead` for invalid slots. Positions are taken in
    float32 as the GPU has them, and the arithmetic follows glsl/photon/photon.glsl."""
    p = np.asarray(positions, np.float32).reshape(-1, 3)
    o = np.asarray(shape.origin, np.float32)
    inv = np.float32(1.0) / np.float32(shape.cell)
    dims = np.asarray(shape.dims, np.int64)
    c = np.floor((p - o) * inv).astype(np.int64)
    c = np.clip(c, 1, dims - 2)
    key = (c[:, 2] * dims[1] + c[:, 1]) * dims[0] + c[:, 0]
    if valid is not None:
        key = np.where(np.asarray(valid, bool), key, shape.dead)
    return key.astype(np.uint32)


def exclusive_scan(counts: np.ndarray) -> np.ndarray:
    """start[i] = sum(counts[:i]); one more entry than counts (the total)."""
    out = np.zeros(len(counts) + 1, np.uint64)
    np.cumsum(counts, out=out[1:])
    return out.astype(np.uint32)


def build_grid(shape: GridShape, keys: np.ndarray):
    """(order, start): photon indices sorted stably by cell, and start indices per cell (cells + 2
    entries: the dead slots' bin, then the total)."""
    keys = np.asarray(keys, np.uint32)
    order = np.argsort(keys, kind="stable").astype(np.uint32)
    counts = np.bincount(keys, minlength=shape.cells + 1)
    return order, exclusive_scan(counts)


def neighbour_runs(shape: GridShape, point) -> list:
    """The 9 runs of cells (first, last + 1) the 3x3x3 search around `point` visits."""
    c = grid_cells(shape, np.asarray(point)[None])[0]
    nx, ny = shape.dims[0], shape.dims[1]
    return [(int(c) + dz * nx * ny + dy * nx - 1, int(c) + dz * nx * ny + dy * nx + 2)
            for dz in (-1, 0, 1) for dy in (-1, 0, 1)]


def grid_query(shape: GridShape, sorted_pos: np.ndarray, start: np.ndarray, point, radius: float) -> np.ndarray:
    """Indices into the sorted photons within `radius` of `point`, found through the grid."""
    p = np.asarray(point, np.float32)
    found = []
    for a, b in neighbour_runs(shape, p):
        idx = np.arange(start[a], start[b])
        d = sorted_pos[idx] - p
        found.append(idx[(d * d).sum(1) <= np.float32(radius) ** 2])
    return np.concatenate(found) if found else np.zeros(0, np.int64)


def brute_query(positions: np.ndarray, point, radius: float, valid=None) -> np.ndarray:
    """Indices of the photons within `radius` of `point`: every photon tested."""
    d = np.asarray(positions, np.float32) - np.asarray(point, np.float32)
    ok = (d * d).sum(1) <= np.float32(radius) ** 2
    if valid is not None:
        ok &= np.asarray(valid, bool)
    return np.nonzero(ok)[0]


# ------------------------------------------------------------------------------ kd-tree

def build_kdtree(positions: np.ndarray):
    """A balanced kd-tree in one array (the paper's baseline, Jensen's photon map): the node of
    range [lo, hi) is the median mid = (lo + hi) // 2 along the range's longest axis, its subtrees
    are [lo, mid) and [mid + 1, hi). Returns (order, axis): photon index and split axis per array
    slot. Built level by level with one stable sort per level (no Python loop per node)."""
    p = np.asarray(positions, np.float32).reshape(-1, 3)
    n = len(p)
    order = np.arange(n, dtype=np.int64)
    axis = np.zeros(n, np.uint32)
    segs = np.array([[0, n]], np.int64) if n else np.zeros((0, 2), np.int64)
    while len(segs):
        lens = segs[:, 1] - segs[:, 0]
        seg_of = np.repeat(np.arange(len(segs)), lens)
        starts = np.cumsum(lens) - lens
        slots = np.arange(lens.sum()) - np.repeat(starts, lens) + np.repeat(segs[:, 0], lens)
        pts = p[order[slots]]
        lo = np.minimum.reduceat(pts, starts, axis=0)
        hi = np.maximum.reduceat(pts, starts, axis=0)
        ax = np.argmax(hi - lo, axis=1)
        vals = pts[np.arange(len(pts)), ax[seg_of]]
        perm = np.lexsort((vals, seg_of))
        order[slots] = order[slots][perm]
        mid = (segs[:, 0] + segs[:, 1]) // 2
        axis[mid] = ax
        left = np.stack([segs[:, 0], mid], 1)
        right = np.stack([mid + 1, segs[:, 1]], 1)
        nxt = np.concatenate([left, right])
        segs = nxt[nxt[:, 1] > nxt[:, 0]]
    return order.astype(np.uint32), axis


def kdtree_query(tree_pos: np.ndarray, axis: np.ndarray, point, radius: float) -> np.ndarray:
    """Indices into the tree's array within `radius` of `point` (the traversal of kdtree.glsl)."""
    q = np.asarray(point, np.float32)
    r2 = np.float32(radius) ** 2
    out, stack = [], [(0, len(tree_pos))]
    while stack:
        lo, hi = stack.pop()
        if lo >= hi:
            continue
        mid = (lo + hi) // 2
        d = tree_pos[mid] - q
        if (d * d).sum() <= r2:
            out.append(mid)
        a = int(axis[mid])
        delta = q[a] - tree_pos[mid, a]
        near, far = ((lo, mid), (mid + 1, hi)) if delta < 0 else ((mid + 1, hi), (lo, mid))
        if delta * delta <= r2:
            stack.append(far)
        stack.append(near)
    return np.array(sorted(out), np.int64)


# ----------------------------------------------------------------------- density estimate

def density(positions, normals, power, point, normal, radius: float, k: int = 0) -> np.ndarray:
    """Irradiance E (rgb) at `point` from the photons within `radius` whose surface faces the
    same way (n . n_photon > 0): sum of power / (pi r^2). k > 0: only the k nearest, over the
    disc through the k-th (Jensen's estimate; r when fewer than k are in range). The radiance a
    Lambertian surface of albedo a sends is a / pi * E."""
    pos = np.asarray(positions, np.float32)
    d = pos - np.asarray(point, np.float32)
    d2 = (d * d).sum(1)
    ok = (d2 <= np.float32(radius) ** 2) & ((np.asarray(normals) @ np.asarray(normal, np.float32)) > 0)
    idx = np.nonzero(ok)[0]
    r2 = float(radius) ** 2
    if k > 0 and len(idx) >= k:
        idx = idx[np.argsort(d2[idx], kind="stable")[:k]]
        r2 = float(d2[idx].max())
    if r2 <= 0:
        return np.zeros(3)
    return np.asarray(power, np.float64)[idx].sum(0) / (np.pi * r2)


# ------------------------------------------------------------------- records on the GPU

def oct_encode(n: np.ndarray) -> np.ndarray:
    """Unit normals -> uint32 (two snorm16 of the octahedral map), as photon.glsl packs them."""
    n = np.asarray(n, np.float64).reshape(-1, 3)
    n = n / np.maximum(np.abs(n).sum(1, keepdims=True), 1e-30)
    xy = n[:, :2].copy()
    neg = n[:, 2] < 0
    xy[neg] = (1 - np.abs(n[neg][:, [1, 0]])) * np.where(n[neg][:, :2] >= 0, 1.0, -1.0)
    q = np.round(np.clip(xy, -1, 1) * 32767).astype(np.int32) & 0xFFFF
    return (q[:, 0] | (q[:, 1] << 16)).astype(np.uint32)


def pack_photons(positions, normals, power, extra=None) -> np.ndarray:
    """(N, 8) uint32 photon records (see the module docstring)."""
    n = len(positions)
    rec = np.zeros((n, PHOTON_WORDS), np.uint32)
    rec[:, 0:3] = np.asarray(positions, np.float32).reshape(n, 3).view(np.uint32)
    rec[:, 3] = oct_encode(normals)
    rec[:, 4:7] = np.asarray(power, np.float32).reshape(n, 3).view(np.uint32)
    if extra is not None:
        rec[:, 7] = extra
    return rec


def unpack_photons(raw) -> dict:
    """Photon records (bytes or uint32 words) -> position, power, normal word, extra word."""
    rec = np.frombuffer(raw, np.uint32).reshape(-1, PHOTON_WORDS) if isinstance(raw, (bytes, bytearray)) \
        else np.asarray(raw, np.uint32).reshape(-1, PHOTON_WORDS)
    return {"position": rec[:, 0:3].view(np.float32).copy(), "normal_bits": rec[:, 3].copy(),
            "power": rec[:, 4:7].view(np.float32).copy(), "extra": rec[:, 7].copy()}


def oct_decode(bits: np.ndarray) -> np.ndarray:
    b = np.asarray(bits, np.uint32)
    x = ((b & 0xFFFF).astype(np.uint16).view(np.int16) / 32767.0).clip(-1, 1)
    y = ((b >> 16).astype(np.uint16).view(np.int16) / 32767.0).clip(-1, 1)
    z = 1 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0)
    x = x + np.where(x >= 0, -t, t)
    y = y + np.where(y >= 0, -t, t)
    n = np.stack([x, y, z], 1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
