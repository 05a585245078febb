"""The binned-SAH building blocks that both BVH builds share, the object-split build (bvh.py
build_bvh) and the SBVH (sbvh.py): box areas, node ranges, the per-node SAH over binned
centroids, and the leaf-or-split decision."""
from __future__ import annotations

import numpy as np


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    d = np.maximum(hi - lo, 0.0)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def _segment_positions(starts: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Concatenated ranges [start, start+count): positions, segment id of each, offsets of segments."""
    offsets = np.zeros(len(counts), np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    seg = np.repeat(np.arange(len(counts)), counts)
    pos = np.arange(int(counts.sum()), dtype=np.int64) - offsets[seg] + starts[seg]
    return pos, seg, offsets


def _binned_sah(c, plo, phi, seg, counts, B, boxes: bool = False):
    """Best SAH split of each node (prims grouped by node, `seg` = node of each) over B bins per axis.

    Returns per-prim bins (n,3), and per node: best cost (sum of area x count, inf when all
    centroids share a bin), axis and split bin (prims with bin > split go right); with `boxes`, also
    the best split's two child boxes (lo, hi) x (left, right), each (A,3) (the SBVH's overlap test).
    """
    A = len(counts)
    offsets = np.zeros(A, np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    cmin = np.minimum.reduceat(c, offsets, axis=0)
    ext = np.maximum.reduceat(c, offsets, axis=0) - cmin
    scale = np.where(ext > 0, B / np.where(ext > 0, ext, 1), 0).astype(np.float32)
    b = ((c - cmin[seg]) * scale[seg]).astype(np.int64)
    np.clip(b, 0, B - 1, out=b)
    cost = np.full((A, 3, B - 1), np.inf, np.float32)
    if boxes:
        kept = np.zeros((4, A, 3, B - 1, 3), np.float32)        # llo, lhi, rlo, rhi per axis and plane
    with np.errstate(invalid="ignore", over="ignore"):
        for axis in range(3):
            key = seg * B + b[:, axis]
            cnt = np.bincount(key, minlength=A * B).reshape(A, B)
            llo, lhi, rlo, rhi = _bin_sweep(key, plo, phi, A, B)
            nl = np.cumsum(cnt, axis=1)[:, :-1]
            nr = counts[:, None] - nl
            c_axis = _half_area(llo[:, :-1], lhi[:, :-1]) * nl + _half_area(rlo[:, 1:], rhi[:, 1:]) * nr
            cost[:, axis] = np.where((nl > 0) & (nr > 0), c_axis, np.inf)
            if boxes:
                kept[:, :, axis] = llo[:, :-1], lhi[:, :-1], rlo[:, 1:], rhi[:, 1:]
    flat = cost.reshape(A, -1)
    best = flat.argmin(axis=1)
    out = b, flat[np.arange(A), best].astype(np.float64), best // (B - 1), best % (B - 1)
    if boxes:
        out += (kept.reshape(4, A, -1, 3)[:, np.arange(A), best],)
    return out


def _leaf_or_split(best_cost, lo, hi, count, too_deep: bool, max_leaf_size, traversal_cost, triangle_cost):
    """Per node of a level: becomes a leaf (one triangle, too deep, or few enough triangles that the
    SAH prefers a leaf), or is split by position (`halve`: no split plane separates its primitives)."""
    valid = np.isfinite(best_cost)
    split_sah = traversal_cost + triangle_cost * best_cost / np.maximum(_half_area(lo.astype(np.float64), hi), 1e-300)
    make_leaf = (count <= 1) | too_deep | ((count <= max_leaf_size) & (~valid | (triangle_cost * count <= split_sah)))
    return make_leaf, ~make_leaf & ~valid


def _bin_sweep(key, lo, hi, A: int, B: int):
    """Boxes (lo, hi) binned by `key` = node * B + bin: each node's prefix boxes (bins 0..k) and suffix
    boxes (bins k..B-1), (A, B, 3) each: llo, lhi, rlo, rhi."""
    blo = np.full((A * B, 3), np.inf, np.float32)
    bhi = np.full((A * B, 3), -np.inf, np.float32)
    for k in range(3):
        np.minimum.at(blo[:, k], key, lo[:, k])
        np.maximum.at(bhi[:, k], key, hi[:, k])
    blo, bhi = blo.reshape(A, B, 3), bhi.reshape(A, B, 3)
    return (np.minimum.accumulate(blo, axis=1), np.maximum.accumulate(bhi, axis=1),
            np.minimum.accumulate(blo[:, ::-1], axis=1)[:, ::-1], np.maximum.accumulate(bhi[:, ::-1], axis=1)[:, ::-1])
