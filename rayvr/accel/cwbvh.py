"""Compressed 8-wide BVH (CWBVH) of Ylitie, Karras and Laine (HPG 2017), collapsed from the binary tree.

Collapse (the paper's dynamic programme)
----------------------------------------
First every binary leaf of more than LEAF_TRIANGLES triangles is halved (by slot order) into a small
subtree, so that every subtree can become a leaf of at most LEAF_TRIANGLES triangles. Then, bottom
up, each binary node n gets C(n, i), the least SAH cost of its subtree cut into at most i subtrees
(i = 1..8), with A(n) its box's half area and T(n) its triangle count:

    C(n, 1)        = min(C_leaf(n), C_internal(n))
    C(n, i > 1)    = min(C(n, i - 1), C_distribute(n, i))
    C_leaf(n)      = A(n) * TRIANGLE_COST * T(n)    (infinite when T(n) > LEAF_TRIANGLES)
    C_internal(n)  = A(n) * NODE_COST + C_distribute(n, 8)
    C_distribute(n, j) = min over 0 < k < j of C(left, k) + C(right, j - k)

vectorised over a tree level at a time. Top down, the root and every subtree that chose "internal"
become one CWBVH node whose children are the subtrees its best distribution names.

Child order (the paper's octant-ordered slots)
----------------------------------------------
Slot s of a node stands for the corner of sign vector v(s) = (s&4 ? + : -, s&2 ? + : -, s&1 ? + : -);
each child is placed greedily in the slot whose corner points most along its centroid's offset from
the node's centre (largest dot product first). A ray whose direction has the octant bits o (bit set:
negative component) then meets the children in the order slot = k ^ o, k = 0..7: first the corner it
enters by. The traversal needs no sort.

GPU layout (one buffer of uvec4, glsl/accel/cwbvh.glsl)
-------------------------------------------------------
Nodes, NODE_WORDS = 20 uint32 = 80 bytes each, root first, then the triangles:

    word 0..2   origin.xyz (float bits): the frame of the quantized child boxes
    word 3      bytes: biased exponents ex, ey, ez (scale = 2^(e-127)), imask (bit s: slot s is internal)
    word 4      child base: node index of the first internal child; the internal children are
                consecutive nodes in slot order (child s = base + bitCount(imask & ((1 << s) - 1)))
    word 5      triangle base: uvec4 index of the node's first triangle in this buffer; its leaf
                children's triangles follow one another, 3 uvec4 each
    word 6..7   8 meta bytes, one per slot: 0 empty; 0b001_11sss (24 + s) internal; leaf: the
                triangle count in unary (0b001, 0b011, 0b111) in the top 3 bits, its first triangle's
                offset from the triangle base (0..23) in the low 5 bits
    word 8..19  8-byte planes q_lo.x, q_lo.y, q_lo.z, q_hi.x, q_hi.y, q_hi.z (byte s: slot s):
                plane = origin + q * scale, the quantization of wide.py (its _quantize), so each
                decoded box contains its child's ulp-widened float box

Triangles: (v0.xyz, original ID bits), (v1.xyz, binary slot bits), (v2.xyz, 0): copies of the binary
layout's triangles in leaf order (no index fetch in the leaf test), carrying the binary BVH's slot so
that Hit.slot names the same slot of the shared triangle buffer in every layout.

Measured on the host (llvmpipe; docs/design.md, cwbvh): the build takes 1.7-3.8 s for 262k
triangles on the shared 2-core host (the binary SAH build 2.2-5.5 s); the room's rays fetch a
quarter of bvh2's nodes (2.9 against 12.1 for primary rays), a 262k-triangle soup's random rays a
third (21 against 62), but shadow rays leaving a surface test 9x the triangles (the quantized box of
their own surface's leaf holds their origin).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..gl.glsl_constants import declare
from .bvh import Bvh, EMPTY_HI, EMPTY_LO, RayWalk, _slab
from .sah import _half_area, _segment_positions
from .wide import _bytes_to_words, _decode, _quantize, _words_to_bytes

WIDTH = 8
LEAF_TRIANGLES = 3      # a leaf child's triangles: 3 bits of unary count in its meta byte
NODE_COST = 1.0         # the paper's SAH constants (c_node, c_prim)
TRIANGLE_COST = 0.3
NODE_WORDS = 20         # 80 bytes
NODE_VEC4 = declare("BVH_CW_NODE_VEC4", NODE_WORDS // 4)
# glsl/accel/cwbvh.glsl widens the ray's per-node plane bases by this fraction of their size
# (> 4 ulp: their rounding is absolute, not relative to t), as bvh_wide.glsl does, so the test of a
# quantized box stays conservative.
BOX_MARGIN = declare("BVH_CW_MARGIN", 1e-6)
TRIANGLE_VEC4 = 3
EMPTY, INTERNAL, LEAF = 0, 1, 2
INTERNAL_META = 0b00100000 | 24   # | slot
_UNARY = np.array([0, 1, 3, 7], np.int64)


@dataclass
class CwBvh:
    """The collapsed tree (final numbering: BFS, a node's internal children consecutive in slot
    order) and its packed buffer; `pack` redoes the boxes from the binary BVH's current vertices."""

    bvh: Bvh
    kind: np.ndarray       # (N, 8) EMPTY / INTERNAL / LEAF per slot
    child: np.ndarray      # (N, 8) internal: node index; else -1
    tri_first: np.ndarray  # (N, 8) leaf: first position in `tri_slot`; else 0
    tri_count: np.ndarray  # (N, 8) leaf: triangles (1..LEAF_TRIANGLES); else 0
    tri_slot: np.ndarray   # (M,) binary triangle slot of each triangle position, leaf order
    depth: np.ndarray      # (N,) depth of each node (root 0)
    build_seconds: float = 0.0
    packed: np.ndarray | None = None   # (N * NODE_VEC4 + M * TRIANGLE_VEC4, 4) uint32

    @property
    def node_count(self) -> int:
        return int(len(self.kind))

    @property
    def nbytes(self) -> int:
        return int(self.packed.nbytes)

    @property
    def group_stack_bound(self) -> int:
        """Stack entries a traversal can hold: one node group a level below the root."""
        return int(self.depth.max()) + 1 if len(self.depth) else 1

    def stats(self) -> dict:
        used = self.kind != EMPTY
        return {"layout": "cwbvh", "nodes": self.node_count, "bytes": self.nbytes,
                "node_bytes": self.node_count * NODE_WORDS * 4, "mean_children": float(used.sum(1).mean()),
                "leaf_children": int((self.kind == LEAF).sum()), "triangles": int(len(self.tri_slot)),
                "depth": int(self.depth.max()) if len(self.depth) else 0, "build_seconds": self.build_seconds}

    def decode(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 8, 3) float32 child boxes lo, hi exactly as the GPU decodes them (slot order)."""
        return decode_boxes(self.packed[:self.node_count * NODE_VEC4].reshape(-1, NODE_WORDS))

    def child_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 8, 3) float32 tight boxes of each slot's child (inverted for empty slots)."""
        return _child_boxes(self.kind, self.child, self.tri_first, self.tri_count, self.tri_slot,
                            self.depth, self.bvh.triangles())


# ====================================================================== collapse

def _split_big_leaves(bvh: Bvh, tri_lo: np.ndarray, tri_hi: np.ndarray):
    """The binary tree with every leaf of more than LEAF_TRIANGLES triangles halved (by slot) until
    none is: (lo, hi, left, right, start, count, depth) of the grown tree (new nodes appended)."""
    lo, hi = [bvh.node_lo.astype(np.float64)], [bvh.node_hi.astype(np.float64)]
    start, count, depth = [bvh.start.astype(np.int64)], [bvh.count.astype(np.int64)], [bvh.depth.astype(np.int64)]
    left, right = bvh.left.astype(np.int64), bvh.right.astype(np.int64)
    big = np.flatnonzero((bvh.left < 0) & (bvh.count > LEAF_TRIANGLES))
    big_start, big_count, big_depth = start[0][big], count[0][big], depth[0][big]
    while len(big):
        m, first_new = len(big), len(left)
        ids = first_new + np.arange(2 * m)
        left = np.concatenate([left, np.full(2 * m, -1)])      # the halves, leaves for now
        right = np.concatenate([right, np.full(2 * m, -1)])
        left[big], right[big] = ids[:m], ids[m:]
        half = big_count // 2
        s = np.concatenate([big_start, big_start + half])
        c = np.concatenate([half, big_count - half])
        pos, _, offsets = _segment_positions(s, c)
        lo.append(np.minimum.reduceat(tri_lo[pos], offsets, axis=0))
        hi.append(np.maximum.reduceat(tri_hi[pos], offsets, axis=0))
        d = np.concatenate([big_depth, big_depth]) + 1
        start.append(s)
        count.append(c)
        depth.append(d)
        again = c > LEAF_TRIANGLES
        big, big_start, big_count, big_depth = ids[again], s[again], c[again], d[again]
    count = np.concatenate(count)
    count[left >= 0] = 0                                       # the halved leaves are internal now
    return np.concatenate(lo), np.concatenate(hi), left, right, np.concatenate(start), count, np.concatenate(depth)


def _solve(lo, hi, left, right, count, depth):
    """The dynamic programme: per node, whether C(n, 1) is a leaf, and for i = 2..8 whether C(n, i)
    keeps C(n, i - 1), else the k of its best distribution (C(left, k) + C(right, i - k))."""
    n = len(left)
    area = _half_area(lo, hi)
    cost = np.full((n, WIDTH + 1), np.inf)
    keep = np.ones((n, WIDTH + 1), bool)
    split = np.zeros((n, WIDTH + 1), np.int64)
    tris = count.astype(np.int64).copy()
    is_leaf = np.zeros(n, bool)
    for d in range(int(depth.max()), -1, -1):
        level = np.flatnonzero(depth == d)
        leaves = level[left[level] < 0]
        cost[leaves, 1:] = (area[leaves] * TRIANGLE_COST * tris[leaves])[:, None]
        is_leaf[leaves] = True
        nodes = level[left[level] >= 0]
        if not len(nodes):
            continue
        l, r = left[nodes], right[nodes]
        tris[nodes] = tris[l] + tris[r]
        dist = np.full((len(nodes), WIDTH + 1), np.inf)
        for j in range(2, WIDTH + 1):
            ks = np.arange(1, j)
            c = cost[l][:, ks] + cost[r][:, j - ks]
            best = c.argmin(axis=1)
            dist[:, j] = c[np.arange(len(nodes)), best]
            split[nodes, j] = ks[best]
        leaf_cost = np.where(tris[nodes] <= LEAF_TRIANGLES, area[nodes] * TRIANGLE_COST * tris[nodes], np.inf)
        internal_cost = area[nodes] * NODE_COST + dist[:, WIDTH]
        is_leaf[nodes] = leaf_cost <= internal_cost
        cost[nodes, 1] = np.minimum(leaf_cost, internal_cost)
        for i in range(2, WIDTH + 1):
            keep[nodes, i] = cost[nodes, i - 1] <= dist[:, i]
            cost[nodes, i] = np.minimum(cost[nodes, i - 1], dist[:, i])
    return is_leaf, keep, split


def _collapse(left, right, start, count, is_leaf, keep, split):
    """Top down: (kind, ref (P, 8), leaf slots (P, 8, 3), depth (P,)) of the provisional nodes
    (creation order, parents first); ref of an internal child: its provisional node."""
    def cut(n, i, out):               # the subtrees of C(n, i)
        while i > 1 and left[n] >= 0:
            if keep[n, i]:
                i -= 1
                continue
            k = int(split[n, i])
            cut(left[n], k, out)
            n, i = right[n], i - k
        out.append(n)

    def slots(n, out):                # the triangle slots of a subtree (a leaf child: at most 3)
        if left[n] < 0:
            out.extend(range(start[n], start[n] + count[n]))
        else:
            slots(left[n], out)
            slots(right[n], out)

    def children(n):
        out = []
        if left[n] < 0:
            if count[n]:
                out.append(n)
        else:
            k = int(split[n, WIDTH])
            cut(left[n], k, out)
            cut(right[n], WIDTH - k, out)
        return out

    kind, ref, leaf_slots, depth = [], [], [], []
    queue = [(0, 0)]                  # (binary node, depth) of each provisional node
    head = 0
    while head < len(queue):
        n, d = queue[head]
        head += 1
        k_row, r_row, s_row = [EMPTY] * WIDTH, [-1] * WIDTH, [[-1] * LEAF_TRIANGLES for _ in range(WIDTH)]
        for s, c in enumerate(children(n)):
            if is_leaf[c]:
                got = []
                slots(c, got)
                k_row[s] = LEAF
                s_row[s][:len(got)] = got
            else:
                k_row[s], r_row[s] = INTERNAL, len(queue)
                queue.append((c, d + 1))
        kind.append(k_row)
        ref.append(r_row)
        leaf_slots.append(s_row)
        depth.append(d)
    return (np.array(kind, np.int64), np.array(ref, np.int64), np.array(leaf_slots, np.int64).reshape(-1, WIDTH, LEAF_TRIANGLES),
            np.array(depth, np.int64))


def _child_boxes(kind, child, tri_first, tri_count, tri_slot, depth, triangles):
    """(N, 8, 3) tight float32 child boxes, bottom up (children are deeper than their parents)."""
    N = len(kind)
    lo = np.full((N, WIDTH, 3), EMPTY_LO, np.float32)
    hi = np.full((N, WIDTH, 3), EMPTY_HI, np.float32)
    for j in range(LEAF_TRIANGLES):
        m = (kind == LEAF) & (j < tri_count)
        t = triangles[tri_slot[tri_first[m] + j]]
        lo[m] = np.minimum(lo[m], t.min(axis=1))
        hi[m] = np.maximum(hi[m], t.max(axis=1))
    for d in range(int(depth.max(initial=0)), 0, -1):
        nodes = np.flatnonzero(depth == d)
        p, s = np.nonzero(np.isin(child, nodes) & (kind == INTERNAL))
        c = child[p, s]
        lo[p, s] = lo[c].min(axis=1)
        hi[p, s] = hi[c].max(axis=1)
    return lo, hi


def octant_slots(lo, hi, used) -> np.ndarray:
    """(N, 8): the slot of each child (children with `used` False fill the slots left over): greedy,
    the (child, slot) pair of the largest dot(child centre - node centre, corner of slot) first."""
    N = len(lo)
    corner = np.array([[1 if s & 4 else -1, 1 if s & 2 else -1, 1 if s & 1 else -1] for s in range(WIDTH)], np.float64)
    centre = 0.5 * (lo.astype(np.float64) + hi.astype(np.float64))
    big = 3e38
    node_lo = np.where(used[..., None], lo, big).min(axis=1)
    node_hi = np.where(used[..., None], hi, -big).max(axis=1)
    node_c = np.where(used.any(axis=1)[:, None], 0.5 * (node_lo + node_hi), 0.0)
    offset = np.where(used[..., None], centre - node_c[:, None], 0.0)
    score = offset @ corner.T                                 # (N, child, slot)
    score = np.where(used[..., None], score, -np.inf)
    slot_of = np.full((N, WIDTH), -1, np.int64)
    rows = np.arange(N)
    for _ in range(WIDTH):
        flat = score.reshape(N, -1)
        pick = np.where(np.isneginf(flat).all(axis=1), -1, flat.argmax(axis=1))
        ok = pick >= 0
        c, s = pick[ok] // WIDTH, pick[ok] % WIDTH
        slot_of[rows[ok], c] = s
        score[rows[ok], c, :] = -np.inf
        score[rows[ok], :, s] = -np.inf
    # unused children take the free slots, in order
    taken = np.zeros((N, WIDTH), bool)
    taken[np.nonzero(slot_of >= 0)[0], slot_of[slot_of >= 0]] = True
    unused_children = np.argsort(slot_of >= 0, axis=1, kind="stable")
    free_slots = np.argsort(taken, axis=1, kind="stable")
    n_free = (~taken).sum(axis=1)
    for i in range(WIDTH):
        m = i < n_free
        slot_of[rows[m], unused_children[m, i]] = free_slots[m, i]
    return slot_of


def build_cwbvh(bvh: Bvh) -> CwBvh:
    """The CWBVH of `bvh` (module docstring), packed."""
    t0 = time.perf_counter()
    tri = bvh.triangles().astype(np.float64)
    tri_lo, tri_hi = tri.min(axis=1), tri.max(axis=1)
    lo, hi, left, right, start, count, depth = _split_big_leaves(bvh, tri_lo, tri_hi)
    is_leaf, keep, split = _solve(lo, hi, left, right, count, depth)
    kind, ref, leaf_slots, pdepth = _collapse(left, right, start, count, is_leaf, keep, split)
    # boxes of the provisional nodes, to place their children in slots
    cnt = (leaf_slots >= 0).sum(axis=2)
    first = np.arange(len(kind) * WIDTH).reshape(-1, WIDTH) * LEAF_TRIANGLES
    plo, phi = _child_boxes(kind, ref, first, cnt, leaf_slots.reshape(-1), pdepth, bvh.triangles())
    slot_of = octant_slots(plo, phi, kind != EMPTY)
    rows = np.arange(len(kind))[:, None]
    perm = np.zeros_like(slot_of)
    perm[rows, slot_of] = np.arange(WIDTH)[None, :]            # perm[n, s]: the child in slot s
    kind, ref, leaf_slots, cnt = kind[rows, perm], ref[rows, perm], leaf_slots[rows, perm], cnt[rows, perm]
    # final numbering: breadth first, a node's internal children consecutive in slot order
    new_of = np.full(len(kind), -1, np.int64)
    order = [0]
    new_of[0] = 0
    for p in order:
        for c in ref[p][kind[p] == INTERNAL]:
            new_of[c] = len(order)
            order.append(int(c))
    order = np.array(order, np.int64)
    kind, ref, leaf_slots, cnt, pdepth = kind[order], ref[order], leaf_slots[order], cnt[order], pdepth[order]
    child = np.where(kind == INTERNAL, new_of[np.maximum(ref, 0)], -1)
    tri_count = np.where(kind == LEAF, cnt, 0)
    tri_first = (np.cumsum(tri_count.ravel()) - tri_count.ravel()).reshape(tri_count.shape)
    take = np.arange(LEAF_TRIANGLES)[None, None, :] < tri_count[..., None]
    tri_slot = leaf_slots[take]                                # row-major: node, slot, triangle
    cw = CwBvh(bvh, kind, child, tri_first, tri_count, tri_slot, pdepth)
    cw.packed = pack(cw)
    cw.build_seconds = time.perf_counter() - t0
    return cw


# ====================================================================== packing

def pack(cw: CwBvh) -> np.ndarray:
    """(N * NODE_VEC4 + M * TRIANGLE_VEC4, 4) uint32: the nodes, then the triangles (module docstring); boxes from the
    binary BVH's current vertices (after `bvh.refit`, the same tree with new boxes)."""
    N, M = cw.node_count, len(cw.tri_slot)
    lo, hi = cw.child_boxes()
    used = cw.kind != EMPTY
    origin, ebias, qlo, qhi = _quantize(lo, hi, used)
    nodes = np.zeros((N, NODE_WORDS), np.uint32)
    nodes[:, 0:3] = origin.view(np.uint32)
    imask = ((cw.kind == INTERNAL) << np.arange(WIDTH)).sum(axis=1)
    nodes[:, 3] = ebias[:, 0] | (ebias[:, 1] << 8) | (ebias[:, 2] << 16) | (imask << 24)
    has = (cw.kind == INTERNAL).any(axis=1)
    first_child = np.where(cw.kind == INTERNAL, cw.child, np.iinfo(np.int64).max).min(axis=1)
    nodes[:, 4] = np.where(has, first_child, 0)
    node_tri = cw.tri_first[:, 0]                              # first triangle position of the node
    nodes[:, 5] = N * NODE_VEC4 + TRIANGLE_VEC4 * node_tri
    meta = np.where(cw.kind == INTERNAL, INTERNAL_META | np.arange(WIDTH),
                    np.where(cw.kind == LEAF, (_UNARY[cw.tri_count] << 5) | (cw.tri_first - node_tri[:, None]), 0))
    nodes[:, 6:8] = _bytes_to_words(meta)
    for p, plane in enumerate([qlo[..., 0], qlo[..., 1], qlo[..., 2], qhi[..., 0], qhi[..., 1], qhi[..., 2]]):
        nodes[:, 8 + 2 * p:10 + 2 * p] = _bytes_to_words(plane)
    tris = np.zeros((M, TRIANGLE_VEC4, 4), np.uint32)
    tris[:, :, :3] = cw.bvh.triangles()[cw.tri_slot].view(np.uint32)
    tris[:, 0, 3] = cw.bvh.prim_ids[cw.tri_slot]
    tris[:, 1, 3] = cw.tri_slot
    return np.concatenate([nodes.reshape(-1, 4), tris.reshape(-1, 4)])


def unpack(nodes: np.ndarray):
    """(origin (N,3) f32, ebias (N,3), imask (N,), child base, triangle base, meta (N,8), q planes
    [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z] each (N,8)) from (N, 20) node words."""
    origin = nodes[:, 0:3].view(np.float32)
    ebias = np.stack([(nodes[:, 3] >> (8 * k)) & 0xFF for k in range(3)], axis=1).astype(np.int64)
    imask = (nodes[:, 3] >> 24).astype(np.int64)
    meta = _words_to_bytes(nodes[:, 6:8])
    planes = [_words_to_bytes(nodes[:, 8 + 2 * p:10 + 2 * p]) for p in range(6)]
    return origin, ebias, imask, nodes[:, 4].astype(np.int64), nodes[:, 5].astype(np.int64), meta, planes


def decode_boxes(nodes: np.ndarray):
    origin, ebias, _, _, _, _, planes = unpack(nodes)
    e = ebias - 127
    lo = np.stack([_decode(origin[:, None, a], e[:, None, a], planes[a]) for a in range(3)], axis=-1)
    hi = np.stack([_decode(origin[:, None, a], e[:, None, a], planes[3 + a]) for a in range(3)], axis=-1)
    return lo, hi


# ====================================================================== reference traversal

def ray_octants(directions) -> np.ndarray:
    """(N,) octant bits of each direction: 4 x < 0, 2 y < 0, 1 z < 0 (as the slab test's inverse)."""
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    return ((d[:, 0] < 0) * 4 + (d[:, 1] < 0) * 2 + (d[:, 2] < 0)).astype(np.int64)


def trace_cwbvh_reference(cw: CwBvh, origins, directions, tmin=0.0, tmax=np.inf, any_hit: bool = False,
                          stats: dict | None = None, octant_order: bool = True):
    """The packed CWBVH walked for all rays at once, decoded from the buffer alone (float64 slabs
    on the float32-decoded boxes): what glsl/accel/cwbvh.glsl does, children in slot order XOR the
    ray's octant, a node's triangles before its children. Returns what `bvh.trace_reference`
    returns; `stats` receives `node_visits` (nodes fetched per ray) and `triangle_tests`.
    `octant_order` False: every ray in slot order (what the octant placement saves, measured)."""
    N = cw.node_count
    nodes = cw.packed[:N * NODE_VEC4].reshape(N, NODE_WORDS)
    tri_words = cw.packed[N * NODE_VEC4:].reshape(-1, TRIANGLE_VEC4, 4)
    tri_slot = tri_words[:, 1, 3].astype(np.int64)             # the triangle's binary slot
    _, _, imask, child_base, tri_base, meta, _ = unpack(nodes)
    lo, hi = (x.astype(np.float64) for x in decode_boxes(nodes))
    w = RayWalk(cw.bvh, origins, directions, tmin, tmax, any_hit, WIDTH * cw.group_stack_bound + 1)
    octant = ray_octants(w.d) if octant_order else np.zeros(w.n, np.int64)
    w.push(np.flatnonzero(w.ok), np.zeros(int(w.ok.sum()), np.int64))
    # rel[imask, s] = bitCount(imask & ((1 << s) - 1)): the internal children stored before slot s
    rel = np.array([[bin(m & ((1 << s) - 1)).count("1") for s in range(WIDTH)] for m in range(256)])
    while True:
        active, node = w.pop()
        if len(active) == 0:
            break
        keep = ~(any_hit & w.occluded[active])
        active, node = active[keep], node[keep]
        entered = []
        for k in range(WIDTH):                 # box tests with the hit as it was at the fetch
            s = k ^ octant[active]
            m = meta[node, s]
            e = (m != 0) & _slab(w.o[active], w.inv[active], lo[node, s], hi[node, s], w.tmin[active],
                                 w.tbest[active], widened=True)
            entered.append((s, m, e))
        for s, m, e in entered:                # the node's triangle group
            leaf = e & ((m & 0x1F) < 24)
            r, n, mm = active[leaf], node[leaf], m[leaf]
            cnt = np.array([0, 1, 0, 2, 0, 0, 0, 3])[mm >> 5]
            first = (tri_base[n] - N * NODE_VEC4) // TRIANGLE_VEC4 + (mm & 0x1F)
            for j in range(LEAF_TRIANGLES):
                t = j < cnt
                w.leaf(r[t], tri_slot[first[t] + j], np.ones(int(t.sum()), np.int64))
        for s, m, e in reversed(entered):      # internal children, the first in visit order on top
            inner = e & ((m & 0x1F) >= 24)
            r, n, ss = active[inner], node[inner], s[inner]
            w.push(r, child_base[n] + rel[imask[n], ss])
    if stats is not None:
        stats["node_visits"] = w.visits
        stats["triangle_tests"] = w.tests
    return w.result()


__all__ = ["CwBvh", "build_cwbvh", "pack", "unpack", "decode_boxes", "octant_slots", "ray_octants",
           "trace_cwbvh_reference", "NODE_WORDS", "LEAF_TRIANGLES"]
