"""Tile frustum culling (HVVR's tile frusta) on the GPU, and its numpy reference.

Rays come in tiles of `TILE_RAYS` (128) consecutive rays; `tile_order` orders a camera's pixels so
that a tile is a 16 x 8 pixel block. glsl/accel/tile_cull.comp (one work group a tile) bounds the
tile's rays with a conservative frustum — four side planes fitted to the rays' direction slopes
about their mean direction, offset to hold every ray origin (a lens, surface points), and a far
plane from tmax — and walks the binary BVH against it into an entry list: at most TILE_ENTRIES
children whose boxes meet the frustum, a cut of the tree under which lies every triangle that any ray
of the tile can hit, listed front to back (by the box's nearest point along the frustum's central
direction c). Each ray is then traced from its tile's list (bvh2.glsl `bvh_traverse_entries`)
instead of from the root, and stops at the first entry wholly beyond its closest hit along c.
Plain per-ray traversal stays the reference: the hits are the same (tests/test_frustum.py), only
the work differs (`RayTracer.trace(work=)` counts it on the GPU). A tile whose rays spread over a
half-space or more is not culled (its list is the root's children); a tile without a valid ray gets
an empty list. The frame's primary rays use the same kernel on their camera's sub-rays, a tile a
TILE_SHAPE pixel block (frame/passes/primary_rays.py, RenderSettings.tile_culling).

`tile_frusta` is the frustum math in numpy (float64), used by the tests to check that every ray's
points lie inside its tile's planes; the GPU writes its planes too (`RayTracer.trace(tile_info=)`).
"""
from __future__ import annotations

import numpy as np

from ..gl.glsl_constants import declare
from ..gl.gpu_layout import TILE_PIXELS, TILE_RAYS
from .bvh import Bvh, valid_rays

TILE_SHAPE = TILE_PIXELS   # pixels of a tile: TILE_RAYS = 16 * 8
SLACK = declare("TILE_SLACK", 1e-5)  # relative slack of the tile tests for float rounding (here and in the shaders)
MIN_COS = declare("TILE_MIN_COS", 0.1)  # cull only tiles whose directions lie within ~84 deg of the mean


def tile_order(width: int, height: int, layers: int = 1, tile: tuple[int, int] = TILE_SHAPE) -> np.ndarray:
    """Permutation of row-major pixel indices (layer, y, x) that lists pixels tile by tile (row-major
    tiles, row-major inside a tile), so consecutive TILE_RAYS rays are one tile; edge tiles are
    partial and shorter. Inverse: `np.argsort(order)`."""
    tw, th = tile
    y, x = np.mgrid[0:height, 0:width]
    key_tile = (y // th) * (-(-width // tw)) + x // tw
    key_in = (y % th) * tw + x % tw
    per_layer = np.lexsort(((key_in).ravel(), key_tile.ravel()))
    return np.concatenate([per_layer + k * width * height for k in range(layers)])


def tile_grid(width: int, height: int, tile: tuple[int, int] = TILE_SHAPE) -> tuple[int, int]:
    """Tiles (across, down) of a width x height image: a frame's tiles per eye (edge tiles partial)."""
    return -(-width // tile[0]), -(-height // tile[1])


def tile_frusta(origins, directions, tmin=0.0, tmax=np.inf, tile: int = TILE_RAYS, slack: float = SLACK):
    """(planes (T,5,4), status (T,)) of each tile of `tile` consecutive rays: planes n.x <= w hold every
    point o + t d (0 <= t <= tmax) of the tile's valid rays; status 0: no valid ray, 1: culled,
    2: too wide to cull (directions beyond MIN_COS of the mean). Float64; see tile_cull.comp."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    n = len(o)
    tmin = np.broadcast_to(np.asarray(tmin, np.float64), (n,))
    tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,))
    ok = valid_rays(d, tmin, tmax)
    T = -(-n // tile)
    planes = np.zeros((T, 5, 4))
    status = np.zeros(T, np.int64)
    for k in range(T):
        sl = slice(k * tile, min(n, (k + 1) * tile))
        m = ok[sl]
        if not m.any():
            continue
        oo, dd, tt = o[sl][m], d[sl][m], tmax[sl][m]
        dn = dd / np.linalg.norm(dd, axis=1, keepdims=True)
        c = dn.sum(0)
        c = c / np.linalg.norm(c) if np.linalg.norm(c) > 0 else np.array([0.0, 0.0, 1.0])
        dc = dn @ c
        if not dc.min() > MIN_COS:
            status[k] = 2
            continue
        u = np.cross(c, [1.0, 0.0, 0.0] if abs(c[0]) < 0.6 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(c, u)
        su, sv = dn @ u / dc, dn @ v / dc
        grow = lambda s, sign: s + sign * slack * (1 + abs(s))   # noqa: E731
        normals = [u - grow(su.max(), 1) * c, -u + grow(su.min(), -1) * c,
                   v - grow(sv.max(), 1) * c, -v + grow(sv.min(), -1) * c]
        omax = np.abs(oo).sum(1).max()
        for j, nrm in enumerate(normals):
            planes[k, j] = [*nrm, (oo @ nrm).max() + 2 * slack * np.linalg.norm(nrm) * omax]
        with np.errstate(over="ignore", invalid="ignore"):
            far = (oo @ c + tt * (dd @ c)).max()
        planes[k, 4] = [*c, far + slack * (abs(far) + omax)]
        status[k] = 1
    return planes, status


def entry_subtrees(bvh: Bvh, entries: np.ndarray) -> list[tuple[int, int]]:
    """Reordered triangle slot ranges [first, last) under each entry (parent << 1 | side), where
    parent is a GPU node number (internal nodes in preorder)."""
    internal = np.flatnonzero(bvh.left >= 0)
    if len(internal) == 0:
        internal = np.zeros(1, np.int64)
    out = []
    for e in np.asarray(entries, np.int64):
        node = internal[e >> 1]
        child = (bvh.left if e & 1 == 0 else bvh.right)[node] if bvh.left[node] >= 0 else node
        out.append(_slot_range(bvh, int(child)))
    return out


def _slot_range(bvh: Bvh, node: int) -> tuple[int, int]:
    first, last = None, None
    stack = [node]
    while stack:
        k = stack.pop()
        if bvh.left[k] < 0:
            a, b = int(bvh.start[k]), int(bvh.start[k] + bvh.count[k])
            first = a if first is None else min(first, a)
            last = b if last is None else max(last, b)
        else:
            stack += [int(bvh.left[k]), int(bvh.right[k])]
    return first, last


__all__ = ["tile_order", "tile_grid", "tile_frusta", "entry_subtrees", "TILE_SHAPE", "MIN_COS"]
