"""Wide BVHs (4 or 8 children per node) collapsed from the binary SAH tree, with quantized child boxes.

Collapse
--------
Every wide node starts as one binary internal node's two children and, while it has fewer than
`width` children, opens the internal child with the largest surface area (the one a random ray is
most likely to enter) into its two children: the greedy SAH-driven collapse of Wald et al. (2008)
and tinybvh's BVH4/BVH8 conversion. Children keep the binary tree's left-to-right order. Binary
leaves stay leaves (the same reordered triangle ranges), so every layout tests the same triangles.
It runs on whole frontiers of wide nodes at once (numpy), one Python step per wide level.

GPU layout (uint32 words, `node_words(width)` per node; width 4: 16 words = 64 bytes, width 8: 28 = 112)
----------------------------------------------------------------------------------------------
    word 0..2   origin.xyz (float bits): the node's decode origin
    word 3      bytes: biased exponents ex, ey, ez of the power-of-two scales (scale = 2^(e-127)),
                then the number of children (children are packed first)
    6 planes    lo.x, hi.x, lo.y, hi.y, lo.z, hi.z, each `width` bytes (width/4 words): child i's plane
                is origin + q * scale, q in 0..255
    width/4     bytes: leaf triangle count of child i (0: internal node)
    width       child i: wide node index (internal) or first reordered triangle (leaf)
8-bit planes with power-of-two scales (the quantization of Ylitie et al. 2017 and tinybvh's
BVH4_GPU): q * scale is exact in float32, so origin + q * scale rounds once, identically in numpy
and GLSL (with or without a fused multiply-add). Each quantized box is made to contain the child's
ulp-widened float box (`bvh.widen`), checked against the float32 decode, so no hit is ever culled.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bvh import Bvh, EMPTY_HI, EMPTY_LO, RayWalk, _slab, widen
from .sah import _half_area

WIDTHS = (4, 8)
MAX_LEAF_COUNT = 255  # one byte per child


def node_words(width: int) -> int:
    """uint32 words per node, a multiple of 4 (one uvec4 fetch each)."""
    n = 4 + 6 * width // 4 + width // 4 + width
    return -(-n // 4) * 4


@dataclass
class WideBvh:
    """A `width`-wide BVH over the binary tree's reordered triangles (`bvh`), packed for the GPU."""

    bvh: Bvh
    width: int
    child: np.ndarray       # (N, W) int64: binary node id of each child slot, -1 = none
    packed: np.ndarray      # (N, node_words) uint32
    stack_bound: int        # the most stack entries a walk that pushes every entered child can hold
    group_stack_bound: int  # the GPU's (node, child mask) stack: one entry per level, the depth + 1

    @property
    def node_count(self) -> int:
        return int(len(self.child))

    @property
    def nbytes(self) -> int:
        return int(self.packed.nbytes)

    def stats(self) -> dict:
        n = (self.child >= 0).sum(axis=1)
        return {"width": self.width, "nodes": self.node_count, "bytes": self.nbytes,
                "mean_children": float(n.mean()), "stack_bound": self.stack_bound,
                "group_stack_bound": self.group_stack_bound,
                "depth": int(self._depth().max()) if self.node_count else 0}

    def _depth(self) -> np.ndarray:
        return _wide_depth(self.child, self.bvh)

    def decode(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, W, 3) float32 child boxes lo, hi exactly as the GPU decodes them."""
        return decode_boxes(self.packed, self.width)


def _wide_depth(child: np.ndarray, bvh: Bvh) -> np.ndarray:
    depth = np.zeros(len(child), np.int64)
    _, wide_of = _internal_children(child, bvh)
    for i in range(len(child)):           # parents precede children (BFS numbering)
        for k in wide_of[i]:
            depth[k] = depth[i] + 1
    return depth


def _internal_children(child: np.ndarray, bvh: Bvh):
    """Per wide node: mask of internal children and their wide node indices (BFS numbering)."""
    internal = (child >= 0) & (bvh.left[np.maximum(child, 0)] >= 0)
    order = np.cumsum(internal.ravel()).reshape(internal.shape)   # k-th internal child -> node k
    wide_of = [order[i][internal[i]] for i in range(len(child))]
    return internal, wide_of


def collapse(bvh: Bvh, width: int = 4) -> np.ndarray:
    """(N, width) binary node ids of the wide nodes' children (-1 = empty), BFS order, root first."""
    if width not in WIDTHS:
        raise ValueError(f"wide BVH width must be one of {WIDTHS}, got {width}")
    if bvh.left[0] < 0:                   # the root is a leaf: one wide node holding it
        out = np.full((1, width), -1, np.int64)
        out[0, 0] = 0
        return out
    lo, hi = bvh.node_lo.astype(np.float64), bvh.node_hi.astype(np.float64)
    area = _half_area(lo, hi)
    rows = []
    frontier = np.array([0])
    while len(frontier):
        F = len(frontier)
        ch = np.full((F, width), -1, np.int64)
        ch[:, 0], ch[:, 1] = bvh.left[frontier], bvh.right[frontier]
        for k in range(2, width):
            open_ = (ch >= 0) & (bvh.left[np.maximum(ch, 0)] >= 0)
            score = np.where(open_, area[np.maximum(ch, 0)], -1.0)
            best = score.argmax(axis=1)
            r = np.flatnonzero(score[np.arange(F), best] >= 0)
            b = ch[r, best[r]]
            ch[r, best[r]] = bvh.left[b]
            ch[r, k] = bvh.right[b]
        # Left-to-right order of the binary tree = preorder number (the Bvh is in preorder).
        ch = np.where(ch >= 0, ch, np.iinfo(np.int64).max)
        ch.sort(axis=1)
        ch = np.where(ch == np.iinfo(np.int64).max, -1, ch)
        rows.append(ch)
        nxt = ch[(ch >= 0) & (bvh.left[np.maximum(ch, 0)] >= 0)]  # row-major: BFS numbering
        frontier = nxt
    return np.concatenate(rows)


def _quantize(lo: np.ndarray, hi: np.ndarray, valid: np.ndarray):
    """Per node origin (N,3) f32, biased exponents (N,3) and q_lo, q_hi (N,W,3) in 0..255 such that
    origin + q * 2^(e-127) (float32) contains each valid child's ulp-widened box."""
    wlo, whi = widen(lo, hi)
    big = np.float32(3e38)
    olo = np.where(valid[..., None], wlo, big).min(axis=1)
    ohi = np.where(valid[..., None], whi, -big).max(axis=1)
    olo = np.where(np.isfinite(olo) & (olo <= ohi), olo, 0).astype(np.float32)
    ohi = np.maximum(ohi, olo)
    ext = ohi.astype(np.float64) - olo.astype(np.float64)
    with np.errstate(divide="ignore"):
        e = np.ceil(np.log2(np.maximum(ext / 255.0, 2.0 ** -126))).astype(np.int64)
    e = np.clip(e, -126, 127)
    for _ in range(4):   # the top plane origin + 255 * scale must reach ohi in float32
        top = (olo + np.float32(255) * _scale(e)).astype(np.float32)
        short = top < ohi
        if not short.any():
            break
        e = np.where(short, e + 1, e)
    s = _scale(e)[:, None, :].astype(np.float64)
    o64 = olo[:, None, :].astype(np.float64)
    qlo = np.clip(np.floor((wlo - o64) / s), 0, 255).astype(np.int64)
    qhi = np.clip(np.ceil((whi - o64) / s), 0, 255).astype(np.int64)
    for _ in range(4):   # float32 decode must stay outside the widened box
        dlo = _decode(olo[:, None, :], e[:, None, :], qlo)
        dhi = _decode(olo[:, None, :], e[:, None, :], qhi)
        bad_lo, bad_hi = (dlo > wlo) & (qlo > 0), (dhi < whi) & (qhi < 255)
        if not (bad_lo.any() or bad_hi.any()):
            break
        qlo = qlo - bad_lo
        qhi = qhi + bad_hi
    qlo = np.where(valid[..., None], qlo, 255)   # empty slots: inverted, never entered
    qhi = np.where(valid[..., None], qhi, 0)
    return olo, e + 127, qlo, qhi


def _scale(e) -> np.ndarray:
    return np.ldexp(np.float32(1), np.asarray(e)).astype(np.float32)


def _decode(origin, e, q) -> np.ndarray:
    return (origin + np.float32(1) * (q.astype(np.float32) * _scale(e))).astype(np.float32)


def pack(bvh: Bvh, child: np.ndarray) -> np.ndarray:
    """(N, node_words) uint32 nodes (layout in the module docstring)."""
    N, W = child.shape
    c = np.maximum(child, 0)
    valid = (child >= 0) & ~((bvh.left[c] < 0) & (bvh.count[c] == 0))   # an empty scene's empty leaf
    lo = np.where(valid[..., None], bvh.node_lo[c], EMPTY_LO).astype(np.float32)
    hi = np.where(valid[..., None], bvh.node_hi[c], EMPTY_HI).astype(np.float32)
    origin, ebias, qlo, qhi = _quantize(lo, hi, valid)
    leaf = valid & (bvh.left[c] < 0)
    count = np.where(leaf, bvh.count[c], 0)
    if count.max(initial=0) > MAX_LEAF_COUNT:
        raise ValueError(f"a BVH leaf holds {int(count.max())} triangles; the wide layouts store at most "
                         f"{MAX_LEAF_COUNT} (build with a smaller max_leaf_size or a larger max_depth)")
    internal = valid & ~leaf
    node_index = np.cumsum(internal.ravel()).reshape(N, W)   # BFS: k-th internal child is node k
    index = np.where(leaf, bvh.start[c], np.where(internal, node_index, 0))
    out = np.zeros((N, node_words(W)), np.uint32)
    out[:, 0:3] = origin.view(np.uint32)
    nchild = valid.sum(axis=1)
    out[:, 3] = ebias[:, 0] | (ebias[:, 1] << 8) | (ebias[:, 2] << 16) | (nchild << 24)
    q = W // 4
    planes = [qlo[..., 0], qhi[..., 0], qlo[..., 1], qhi[..., 1], qlo[..., 2], qhi[..., 2]]
    for p, plane in enumerate(planes + [count]):
        out[:, 4 + p * q:4 + (p + 1) * q] = _bytes_to_words(plane)
    out[:, 4 + 7 * q:4 + 7 * q + W] = index.astype(np.uint32)
    return out


def _bytes_to_words(b: np.ndarray) -> np.ndarray:
    b = b.astype(np.uint32).reshape(len(b), -1, 4)
    return b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16) | (b[..., 3] << 24)


def _words_to_bytes(w: np.ndarray) -> np.ndarray:
    return ((w[..., None] >> (8 * np.arange(4, dtype=np.uint32))) & 0xFF).reshape(len(w), -1).astype(np.int64)


def unpack(packed: np.ndarray, width: int):
    """(origin, ebias, nchild, q planes (6,N,W), counts (N,W), index (N,W)) from packed nodes."""
    q = width // 4
    origin = packed[:, 0:3].view(np.float32)
    ebias = np.stack([(packed[:, 3] >> (8 * k)) & 0xFF for k in range(3)], axis=1).astype(np.int64)
    nchild = (packed[:, 3] >> 24).astype(np.int64)
    planes = [_words_to_bytes(packed[:, 4 + p * q:4 + (p + 1) * q]) for p in range(7)]
    index = packed[:, 4 + 7 * q:4 + 7 * q + width].astype(np.int64)
    return origin, ebias, nchild, planes[:6], planes[6], index


def decode_boxes(packed: np.ndarray, width: int):
    origin, ebias, _, planes, _, _ = unpack(packed, width)
    e = ebias - 127
    lo = np.stack([_decode(origin[:, None, a], e[:, None, a], planes[2 * a]) for a in range(3)], axis=-1)
    hi = np.stack([_decode(origin[:, None, a], e[:, None, a], planes[2 * a + 1]) for a in range(3)], axis=-1)
    return lo, hi


def stack_bound(bvh: Bvh, child: np.ndarray) -> int:
    """The largest stack a traversal that pushes every entered internal child and pops one can need:
    over all root-to-node paths, sum over the path's nodes of (internal children - 1), plus one."""
    internal, wide_of = _internal_children(child, bvh)
    need = np.zeros(len(child), np.int64)     # stack held when node is popped, worst case
    best = 0
    for i in range(len(child)):
        k = len(wide_of[i])
        best = max(best, need[i] + k)
        for j, w in enumerate(wide_of[i]):
            need[w] = need[i] + k - 1
    return int(best)


def build_wide(bvh: Bvh, width: int = 4) -> WideBvh:
    child = collapse(bvh, width)
    return WideBvh(bvh, width, child, pack(bvh, child), stack_bound(bvh, child),
                   int(_wide_depth(child, bvh).max()) + 1)


# ====================================================================== reference traversal

def trace_wide_reference(wide: WideBvh, origins, directions, tmin=0.0, tmax=np.inf, any_hit: bool = False,
                         stats: dict | None = None):
    """The packed wide BVH walked for all rays at once (float64 slabs on the float32-decoded boxes):
    what glsl/accel/bvh_wide.glsl does, in numpy. Returns what `bvh.trace_reference` returns.
    `stats` receives `node_visits` (wide nodes fetched per ray, children in slot order: no
    nearest-first) and `triangle_tests`."""
    W = wide.width
    w = RayWalk(wide.bvh, origins, directions, tmin, tmax, any_hit, wide.stack_bound + 1)
    w.push(np.flatnonzero(w.ok), np.zeros(int(w.ok.sum()), np.int64))
    lo, hi = (x.astype(np.float64) for x in wide.decode())
    _, _, nchild, _, count, index = unpack(wide.packed, W)
    while True:
        active, node = w.pop()
        if len(active) == 0:
            break
        for c in range(W):
            m = (c < nchild[node]) & ~(any_hit & w.occluded[active])
            r, nd = active[m], node[m]
            enter = _slab(w.o[r], w.inv[r], lo[nd, c], hi[nd, c], w.tmin[r], w.tbest[r], widened=True)
            r, nd = r[enter], nd[enter]
            cnt = count[nd, c]
            leaf = cnt > 0
            w.leaf(r[leaf], index[nd[leaf], c], cnt[leaf])
            w.push(r[~leaf], index[nd[~leaf], c])
    if stats is not None:
        stats["node_visits"] = w.visits
        stats["triangle_tests"] = w.tests
    return w.result()


__all__ = ["WideBvh", "WIDTHS", "build_wide", "collapse", "pack", "unpack", "decode_boxes", "node_words",
           "trace_wide_reference", "stack_bound"]
