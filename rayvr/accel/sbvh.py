"""Spatial splits in the BVH build (SBVH; Stich, Friedrich & Dietrich 2009), level at a time in numpy.

`build_bvh(..., spatial_splits=True)` lands here. Like the binned-SAH build of bvh.py, every node of a
tree level is binned, scanned and split together; but a node holds *references* (a triangle and a
box around the part of it the node is responsible for) instead of whole triangles, and a node may be
split at a plane that cuts references in two:

* object split: the binned SAH over the references' box centroids (sah._binned_sah);
* spatial split, tried only where the object split's two children overlap by more than
  `split_alpha` x the root's surface area (the paper's alpha), in nodes of at least
  `spatial_min_refs` references (bvh.SPATIAL_MIN_REFS: small nodes gain little and cost most of the
  build): `bins` equal slabs per axis over the
  node's box; each reference is clipped exactly to every slab it spans (`clip_boxes`: the box of the
  triangle polygon cut by the slab, intersected with the reference's box), the clipped boxes make
  the bin boxes, entry/exit counts the references on each side of a plane;
* the cheaper of the two wins; a spatial split sends a reference cut by its plane to both children,
  each with its clipped box, unless moving it whole to one side lowers the SAH (reference
  unsplitting, the paper's section 4.4: `_unsplit`, each reference judged against the binned split).

Duplication is bounded: a level's spatial splits are accepted, largest SAH gain per duplicated
reference first, while the references of the whole tree stay within (1 + max_duplication) x the
triangles; the remaining nodes take their object split.

How a duplicated triangle is stored (the least invasive representation): a `Bvh` already keeps one
*slot* per leaf entry with that slot's own vertex indices (`indices`) and the caller's triangle ID
(`prim_ids`), and the GPU triangle buffer already stores that ID in each 48-byte record. An SBVH
simply has more slots than triangles: a triangle cut into k references fills k slots, each with the
full triangle and its original ID. Nothing that reads leaves changes: every layout (bvh2, the wide
bvh4/bvh8 collapsed from it, the tile culling) and the numpy traversals intersect the full triangle
and report the original ID; closest hits stay exact because the ray's t-interval, not the clipped
box, decides which intersection is kept (a duplicate just finds the same t again), and any-hit is
unaffected. The refit (numpy `Bvh.refit`, GPU refit.comp) recomputes a leaf's box from its slots'
full triangles: after vertices move, a duplicated reference's box grows back to its whole triangle,
which is conservative (the clipped boxes are a build-time optimisation and are not kept).
"""
from __future__ import annotations

import numpy as np

from .sah import _bin_sweep, _binned_sah, _half_area, _leaf_or_split, _segment_positions


_progress_bars = True  # set_progress_bars


def set_progress_bars(enabled: bool) -> None:
    """Whether a build that asks for `progress` shows its tqdm bar, for the whole process: a
    Renderer builds its BVH deep inside a frame, so `rayvr capture -q` says it here."""
    global _progress_bars
    _progress_bars = enabled


def clip_boxes(tri: np.ndarray, axis: int, lo: np.ndarray, hi: np.ndarray):
    """Boxes (lo, hi) float64 (P,3) of each triangle tri (P,3,3) float64 cut to the slab
    lo <= x[axis] <= hi (P,): the bounds of the clipped polygon, whose corners are the vertices inside
    the slab and the edges' crossings of its two planes. An empty cut gives lo > hi (+inf, -inf)."""
    x = tri[:, :, axis]
    lo_c, hi_c = lo[:, None], hi[:, None]
    inside = ((x >= lo_c) & (x <= hi_c))[..., None]
    out_lo = _over3(np.fmin, np.where(inside, tri, np.inf))
    out_hi = _over3(np.fmax, np.where(inside, tri, -np.inf))
    b, xb = np.roll(tri, -1, axis=1), np.roll(x, -1, axis=1)   # edges v0v1, v1v2, v2v0
    with np.errstate(divide="ignore", invalid="ignore"):
        for c in (lo_c, hi_c):
            cross = (x - c) * (xb - c) < 0                      # the edge passes through the plane
            s = np.where(cross, (c - x) / (xb - x), np.nan)     # NaN: no point (fmin/fmax skip it)
            p = tri + s[..., None] * (b - tri)
            out_lo = np.fmin(out_lo, _over3(np.fmin, p))
            out_hi = np.fmax(out_hi, _over3(np.fmax, p))
    empty = out_lo[:, axis] > out_hi[:, axis]
    out_lo[:, axis] = np.where(empty, np.inf, np.maximum(_over3(np.fmin, x), lo))   # exact along the axis
    out_hi[:, axis] = np.where(empty, -np.inf, np.minimum(_over3(np.fmax, x), hi))
    return out_lo, out_hi


def _over3(op, a):
    """op over the 3 entries of axis 1 (numpy's reductions over a short middle axis are slow)."""
    return op(op(a[:, 0], a[:, 1]), a[:, 2])


def _round_out(lo64: np.ndarray, hi64: np.ndarray):
    """float64 box -> the smallest float32 box containing it."""
    lo, hi = lo64.astype(np.float32), hi64.astype(np.float32)
    lo = np.where(lo > lo64, np.nextafter(lo, np.float32(-np.inf)), lo)
    hi = np.where(hi < hi64, np.nextafter(hi, np.float32(np.inf)), hi)
    return lo, hi


def _clip_refs(tri64, ref_lo, ref_hi, axis, lo, hi):
    """References cut to slabs: box of (triangle cut to the slab) intersected with the reference's
    box, rounded outwards to float32 (so it still holds every point of the triangle it stands for)."""
    clo, chi = clip_boxes(tri64, axis, lo, hi)
    clo, chi = _round_out(clo, chi)
    return np.maximum(clo, ref_lo), np.minimum(chi, ref_hi)


def _spatial_sah(tri64, r_lo, r_hi, seg, counts, node_lo, node_hi, B):
    """Best spatial split of each node over B equal slabs per axis of its box (refs grouped by node).

    Returns per node: cost (area x references on both sides, inf if none), axis, plane position
    (float64, the upper plane of the split bin), the two children's boxes (4,A,3: llo, lhi, rlo, rhi)
    and reference counts (2,A), and per-ref first/last bins (n,3) for the partition.
    """
    A = len(counts)
    rows = np.arange(A)
    cost = np.full((A, 3), np.inf)
    split_bin = np.zeros((A, 3), np.int64)
    boxes = np.zeros((3, 4, A, 3))
    sides = np.zeros((3, 2, A), np.int64)
    first = np.zeros((len(seg), 3), np.int64)
    last = np.zeros((len(seg), 3), np.int64)
    org = node_lo.astype(np.float64)
    width = (node_hi.astype(np.float64) - org) / B
    for axis in range(3):
        wa = width[:, axis]
        inv = np.where(wa > 0, 1.0 / np.where(wa > 0, wa, 1.0), 0.0)
        f = np.clip(((r_lo[:, axis] - org[seg, axis]) * inv[seg]).astype(np.int64), 0, B - 1)
        l = np.clip(((r_hi[:, axis] - org[seg, axis]) * inv[seg]).astype(np.int64), 0, B - 1)
        l = np.maximum(l, f)
        first[:, axis], last[:, axis] = f, l
        enter = np.bincount(seg * B + f, minlength=A * B).reshape(A, B)
        leave = np.bincount(seg * B + l, minlength=A * B).reshape(A, B)
        # One (reference, bin) pair per bin a reference spans: its part inside that slab.
        span = l - f + 1
        pos, ref, _ = _segment_positions(f, span)               # pos = the bin of each pair
        s = seg[ref]
        blo = org[s, axis] + pos * wa[s]
        bhi = np.where(pos == B - 1, node_hi[s, axis].astype(np.float64), org[s, axis] + (pos + 1) * wa[s])
        plo, phi = r_lo[ref], r_hi[ref]                         # inside one slab: the box as it is
        cut = np.flatnonzero(span[ref] > 1)
        if len(cut):
            cr = ref[cut]
            plo[cut], phi[cut] = _clip_refs(tri64[cr], r_lo[cr], r_hi[cr], axis, blo[cut], bhi[cut])
        llo, lhi, rlo, rhi = _bin_sweep(s * B + pos, plo, phi, A, B)
        nl = np.cumsum(enter, axis=1)[:, :-1]                   # refs starting at or left of the plane
        nr = counts[:, None] - np.cumsum(leave, axis=1)[:, :-1]   # refs ending right of it
        with np.errstate(invalid="ignore", over="ignore"):
            c = (_half_area(llo[:, :-1].astype(np.float64), lhi[:, :-1]) * nl
                 + _half_area(rlo[:, 1:].astype(np.float64), rhi[:, 1:]) * nr)
        c = np.where((nl > 0) & (nr > 0) & (wa[:, None] > 0), c, np.inf)
        k = split_bin[:, axis] = c.argmin(axis=1)
        cost[:, axis] = c[rows, k]
        boxes[axis] = llo[rows, k], lhi[rows, k], rlo[rows, k + 1], rhi[rows, k + 1]
        sides[axis] = nl[rows, k], nr[rows, k]
    best_axis = cost.argmin(axis=1)
    k = split_bin[rows, best_axis]
    plane = org[rows, best_axis] + (k + 1) * width[rows, best_axis]
    return (cost[rows, best_axis], best_axis, k, plane, boxes[best_axis, :, rows].transpose(1, 0, 2),
            sides[best_axis, :, rows].T, first, last)


def _unsplit(lo, hi, child_boxes, n_sides):
    """Reference unsplitting (the paper's section 4.4) for references a spatial split cuts: 0 puts the
    whole reference (box lo, hi) left, 1 right, 2 keeps it in both, whichever gives the lowest SAH
    given the split's child boxes and counts. Each reference is judged against the split as binned
    (not after its neighbours' moves), which keeps it one vectorised step."""
    llo, lhi, rlo, rhi = (b.astype(np.float64) for b in child_boxes)
    nl, nr = n_sides
    al, ar = _half_area(llo, lhi), _half_area(rlo, rhi)
    keep = al * nl + ar * nr
    to_left = _half_area(np.minimum(llo, lo), np.maximum(lhi, hi)) * nl + ar * (nr - 1)
    to_right = al * (nl - 1) + _half_area(np.minimum(rlo, lo), np.maximum(rhi, hi)) * nr
    return np.argmin(np.stack([to_left, to_right, keep]), axis=0)


def _overlap_area(boxes):
    """Half surface area of the overlap of each best object split's children (boxes: llo, lhi, rlo,
    rhi from _binned_sah), 0 when they are apart."""
    lo = np.maximum(boxes[0], boxes[2]).astype(np.float64)
    hi = np.minimum(boxes[1], boxes[3]).astype(np.float64)
    return np.where((hi >= lo).all(axis=1), _half_area(lo, hi), 0.0)


def build_sbvh(V, I, *, bins, max_leaf_size, max_depth, traversal_cost, triangle_cost, split_alpha,
               max_duplication, progress, params, spatial_min_refs: int = 1, unsplit: bool = True):
    """The SBVH build (module docstring); V, I checked by build_bvh, T > 0. Its per-level node
    records (lo, hi, start, count, left, right lists) and reference slots, which bvh._finish makes
    the Bvh of."""
    T = len(I)
    tri64 = V[I].astype(np.float64)
    tlo, thi = V[I].min(axis=1), V[I].max(axis=1)
    ref_limit = int(np.floor(T * (1.0 + max_duplication)))
    # References of the current level, grouped by node (seg = node within the level).
    r_tri = np.arange(T, dtype=np.int64)
    r_lo, r_hi = tlo, thi
    seg = np.zeros(T, np.int64)
    level_lo, level_hi = tlo.min(axis=0, keepdims=True), thi.max(axis=0, keepdims=True)
    level_count = np.array([T], np.int64)
    root_area = float(_half_area(level_lo.astype(np.float64), level_hi)[0])
    lo_list, hi_list, start_list, count_list, left_list, right_list = [level_lo], [level_hi], [], [level_count], [], []
    slots: list[np.ndarray] = []                                # references of the leaves, in emission order
    n_slots = 0
    total_refs = T
    spatial_nodes = 0
    n_nodes, depth, B = 1, 0, int(bins)
    bar = None
    if progress and _progress_bars:
        from tqdm import tqdm
        bar = tqdm(desc="SBVH build", unit=" refs", total=T, leave=False)

    while len(level_count):
        A = len(level_count)
        # --- object split (binned SAH over the reference boxes' centroids), as the SAH build does
        nb = np.minimum(B, 2 ** np.ceil(np.log2(np.maximum(level_count, 2))).astype(np.int64))
        nb[(level_count <= 1) | (depth >= max_depth)] = 0
        o_cost = np.full(A, np.inf)
        o_axis = np.zeros(A, np.int64)
        o_bin = np.zeros(A, np.int64)
        overlap = np.zeros(A)
        b = np.zeros((len(seg), 3), np.int64)
        cen = (r_lo + r_hi) * np.float32(0.5)
        for g in np.unique(nb[nb > 0]):
            nodes = np.flatnonzero(nb == g)
            in_g = (nb == g)[seg]
            local = np.full(A, -1, np.int64)
            local[nodes] = np.arange(len(nodes))
            b[in_g], o_cost[nodes], o_axis[nodes], o_bin[nodes], boxes = _binned_sah(
                cen[in_g], r_lo[in_g], r_hi[in_g], local[seg[in_g]], level_count[nodes], int(g), boxes=True)
            overlap[nodes] = _overlap_area(boxes)
        # --- spatial split where the object split's children overlap (the paper's alpha test)
        spatial = np.zeros(A, bool)
        s_cost = np.full(A, np.inf)
        s_axis = np.zeros(A, np.int64)
        s_bin = np.zeros(A, np.int64)
        s_plane = np.zeros(A)
        s_dups = np.zeros(A, np.int64)
        s_boxes = np.zeros((4, A, 3))
        s_sides = np.zeros((2, A), np.int64)
        first = last = None
        try_s = ((nb > 0) & (overlap > split_alpha * root_area) & (total_refs < ref_limit)
                 & (level_count >= spatial_min_refs))
        if try_s.any():
            cand = np.flatnonzero(try_s)
            in_c = try_s[seg]
            local = np.full(A, -1, np.int64)
            local[cand] = np.arange(len(cand))
            c_cost, c_axis, c_bin, c_plane, c_boxes, c_sides, f, l = _spatial_sah(
                tri64[r_tri[in_c]], r_lo[in_c], r_hi[in_c], local[seg[in_c]], level_count[cand],
                level_lo[cand], level_hi[cand], B)
            win = c_cost < o_cost[cand]
            if win.any():
                # references cut by the plane: duplicates a spatial split adds
                cs = local[seg[in_c]]
                fa, la = f[np.arange(len(cs)), c_axis[cs]], l[np.arange(len(cs)), c_axis[cs]]
                cut = np.bincount(cs, weights=(fa <= c_bin[cs]) & (la > c_bin[cs]), minlength=len(cand))
                node_area = np.maximum(_half_area(level_lo[cand].astype(np.float64), level_hi[cand]), 1e-300)
                gain = (o_cost[cand] - c_cost) / node_area / np.maximum(cut, 1)
                pick = np.flatnonzero(win)
                pick = pick[np.argsort(-gain[pick], kind="stable")]
                room = ref_limit - total_refs
                pick = pick[np.cumsum(cut[pick]) <= room]
                nodes = cand[pick]
                spatial[nodes] = True
                s_cost[nodes], s_axis[nodes], s_bin[nodes] = c_cost[pick], c_axis[pick], c_bin[pick]
                s_plane[nodes], s_dups[nodes] = c_plane[pick], cut[pick].astype(np.int64)
                s_boxes[:, nodes], s_sides[:, nodes] = c_boxes[:, pick], c_sides[:, pick]
                first = np.zeros((len(seg), 3), np.int64)
                last = np.zeros((len(seg), 3), np.int64)
                first[in_c], last[in_c] = f, l
        best_cost = np.where(spatial, s_cost, o_cost)
        make_leaf, halve = _leaf_or_split(best_cost, level_lo, level_hi, level_count, depth >= max_depth,
                                          max_leaf_size, traversal_cost, triangle_cost)
        spatial &= ~make_leaf
        total_refs += int(s_dups[spatial].sum())
        spatial_nodes += int(spatial.sum())

        # --- leaves: their references become slots
        starts = np.zeros(A, np.int64)
        leaf_nodes = np.flatnonzero(make_leaf)
        starts[leaf_nodes] = n_slots + np.concatenate([[0], np.cumsum(level_count[leaf_nodes])[:-1]])
        in_leaf = make_leaf[seg]
        slots.append(r_tri[in_leaf])
        n_slots += int(in_leaf.sum())
        start_list.append(starts)
        if bar is not None:
            bar.total = total_refs
            bar.update(int(in_leaf.sum()))
        left_ids = np.full(A, -1, np.int64)
        right_ids = np.full(A, -1, np.int64)
        split = np.flatnonzero(~make_leaf)
        left_list.append(left_ids)
        right_list.append(right_ids)
        if len(split) == 0:
            break

        # --- partition: side 0 left, 1 right, 2 both (cut by a spatial split's plane)
        keep = ~in_leaf
        k_seg, k_tri, k_lo, k_hi = seg[keep], r_tri[keep], r_lo[keep], r_hi[keep]
        idx = np.flatnonzero(keep)
        node_first = np.searchsorted(seg, np.arange(A))
        rank = idx - node_first[k_seg]
        go_right = np.where(halve[k_seg], rank >= level_count[k_seg] // 2,
                            b[keep, o_axis[k_seg]] > o_bin[k_seg])
        side = go_right.astype(np.int64)
        sp = spatial[k_seg]
        if sp.any():
            rows = np.flatnonzero(sp)
            ax = s_axis[k_seg[rows]]
            fa, la, kb = first[idx[rows], ax], last[idx[rows], ax], s_bin[k_seg[rows]]
            side[rows] = np.where(la <= kb, 0, np.where(fa > kb, 1, 2))
        rank_of = np.full(A, -1, np.int64)
        rank_of[split] = np.arange(len(split))
        both = np.flatnonzero(side == 2)
        if len(both) and unsplit:
            n = k_seg[both]
            side[both] = _unsplit(k_lo[both], k_hi[both], s_boxes[:, n], s_sides[:, n])
            total_refs -= int((side[both] != 2).sum())
            both = both[side[both] == 2]
        c_lo_l, c_hi_l, c_lo_r, c_hi_r = k_lo.copy(), k_hi.copy(), k_lo.copy(), k_hi.copy()
        for axis in range(3):
            r = both[s_axis[k_seg[both]] == axis]
            if len(r):
                plane, inf, t = s_plane[k_seg[r]], np.full(len(r), np.inf), tri64[k_tri[r]]
                c_lo_l[r], c_hi_l[r] = _clip_refs(t, k_lo[r], k_hi[r], axis, -inf, plane)
                c_lo_r[r], c_hi_r[r] = _clip_refs(t, k_lo[r], k_hi[r], axis, plane, inf)
        to_l, to_r = side != 1, side != 0
        child = np.concatenate([2 * rank_of[k_seg[to_l]], 2 * rank_of[k_seg[to_r]] + 1])
        o = np.argsort(child, kind="stable")                    # grouped by child, order kept
        seg = child[o]
        r_tri = np.concatenate([k_tri[to_l], k_tri[to_r]])[o]
        r_lo = np.concatenate([c_lo_l[to_l], c_lo_r[to_r]])[o]
        r_hi = np.concatenate([c_hi_l[to_l], c_hi_r[to_r]])[o]

        S = len(split)
        left_ids[split] = n_nodes + 2 * np.arange(S)
        right_ids[split] = left_ids[split] + 1
        level_count = np.bincount(seg, minlength=2 * S).astype(np.int64)
        offs = np.concatenate([[0], np.cumsum(level_count)[:-1]])
        level_lo = np.minimum.reduceat(r_lo, offs, axis=0)
        level_hi = np.maximum.reduceat(r_hi, offs, axis=0)
        n_nodes += 2 * S
        lo_list.append(level_lo)
        hi_list.append(level_hi)
        count_list.append(level_count)
        depth += 1
    if bar is not None:
        bar.close()
    params.update(references=n_slots, spatial_split_nodes=spatial_nodes)
    return (lo_list, hi_list, start_list, count_list, left_list, right_list), np.concatenate(slots)
