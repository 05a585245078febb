"""The compressed 8-wide BVH (accel/cwbvh.py, glsl/accel/cwbvh.glsl) against the binary reference:
its collapse against a brute force, its decoded boxes, its octant order, its numpy walk, the GPU
traversal (hits bit for bit bvh2's) and a rendered frame."""
from __future__ import annotations

import functools
import itertools

import numpy as np
import pytest

from rayvr.accel.bvh import build_bvh, trace_reference, widen
from rayvr.accel.cwbvh import (EMPTY, INTERNAL, LEAF, LEAF_TRIANGLES, NODE_COST, NODE_WORDS, TRIANGLE_COST,
                               build_cwbvh, octant_slots, ray_octants, trace_cwbvh_reference, unpack)
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer
from rayvr.accel.sah import _half_area
from test_traversal_gpu import cube, cube_edge_rays, rays_at, soup


def room_rays(n, seed):
    """The built-in room's triangles and random rays from inside it."""
    from rayvr.scene.loader import load
    scene = load()
    v, f = np.asarray(scene.vertices, np.float32), np.asarray(scene.indices, np.int64)
    rng = np.random.default_rng(seed)
    lo, hi = v.min(0), v.max(0)
    o = rng.uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), (n, 3)).astype(np.float32)
    return v, f, o, rng.normal(size=(n, 3)).astype(np.float32)


def cases():
    v, f = soup(1500, seed=1)
    o, d = rays_at(v, 2500, seed=3)
    yield "soup", v, f, o.astype(np.float32), d.astype(np.float32)
    yield "room", *room_rays(2500, seed=4)


def collapsed_cost(cw) -> float:
    """The SAH cost of the built tree: every node's area x NODE_COST, every leaf child's area x
    TRIANGLE_COST x its triangles (the boxes the build made, float64 areas)."""
    lo, hi = (x.astype(np.float64) for x in cw.child_boxes())
    area = _half_area(lo, hi)
    used = cw.kind != EMPTY
    node_area = _half_area(np.where(used[..., None], lo, np.inf).min(1), np.where(used[..., None], hi, -np.inf).max(1))
    leaf = cw.kind == LEAF
    return float(NODE_COST * node_area.sum() + TRIANGLE_COST * (area[leaf] * cw.tri_count[leaf]).sum())


def brute_force_cost(bvh) -> float:
    """Least SAH cost over every collapse of the binary tree into nodes of at most 8 children, each
    child a subtree of the node's: a leaf of at most LEAF_TRIANGLES triangles or another node."""
    area = _half_area(bvh.node_lo.astype(np.float64), bvh.node_hi.astype(np.float64))

    @functools.cache
    def tris(n):
        return int(bvh.count[n]) if bvh.left[n] < 0 else tris(bvh.left[n]) + tris(bvh.right[n])

    @functools.cache
    def cuts(n):                     # every set of at most 8 subtrees that covers n's subtree
        out = [(n,)]
        if bvh.left[n] >= 0:
            out += [a + b for a, b in itertools.product(cuts(bvh.left[n]), cuts(bvh.right[n])) if len(a + b) <= 8]
        return out

    @functools.cache
    def child(n):
        leaf = area[n] * TRIANGLE_COST * tris(n) if tris(n) <= LEAF_TRIANGLES else np.inf
        return min(leaf, node(n)) if bvh.left[n] >= 0 else leaf

    @functools.cache
    def node(n):
        best = min(sum(child(c) for c in a + b) for a, b in itertools.product(cuts(bvh.left[n]), cuts(bvh.right[n]))
                   if len(a + b) <= 8)
        return area[n] * NODE_COST + best
    return node(0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_collapse_is_the_least_sah_cost_of_every_collapse(seed):
    v, f = soup(14, seed=seed)
    bvh = build_bvh(v, f, max_leaf_size=1)
    assert bvh.max_depth >= 4
    assert collapsed_cost(build_cwbvh(bvh)) == pytest.approx(brute_force_cost(bvh), rel=1e-9)


def test_every_triangle_once_leaves_small_internal_children_consecutive():
    v, f = soup(3000, seed=2)
    bvh = build_bvh(v, f)                                     # leaves up to 8 triangles: halved for the layout
    assert bvh.count.max() > LEAF_TRIANGLES
    cw = build_cwbvh(bvh)
    assert np.array_equal(np.sort(cw.tri_slot), np.arange(bvh.reference_count))
    assert cw.tri_count.max() <= LEAF_TRIANGLES and (cw.tri_count[cw.kind == LEAF] >= 1).all()
    assert cw.tri_count.sum(1).max() <= 24
    assert NODE_WORDS * 4 == 80                               # 80-byte nodes: 5 uvec4
    nodes = cw.packed[:cw.node_count * 5].reshape(-1, NODE_WORDS)
    _, _, imask, base, tri_base, meta, _ = unpack(nodes)
    for n in range(cw.node_count):
        inner = np.flatnonzero(cw.kind[n] == INTERNAL)
        assert np.array_equal(cw.child[n, inner], base[n] + np.arange(len(inner)))   # slot order, one base
        assert imask[n] == sum(1 << int(s) for s in inner)
    # each node but the root has one parent; the triangle section follows the nodes
    assert np.array_equal(np.sort(cw.child[cw.kind == INTERNAL]), np.arange(1, cw.node_count))
    assert tri_base.min() == cw.node_count * 5
    assert (meta[cw.kind == EMPTY] == 0).all() and (meta[cw.kind == INTERNAL] & 0x1F >= 24).all()
    assert cw.stats()["mean_children"] > 4 and cw.build_seconds > 0


@pytest.mark.parametrize("offset,scale", [(0.0, 1.0), (1e5, 1.0), (0.0, 1e-3), (-3e4, 40.0)])
def test_decoded_boxes_contain_their_children(offset, scale):
    v, f = soup(800, seed=5)
    v = (v * scale + offset).astype(np.float32)
    cw = build_cwbvh(build_bvh(v, f))
    lo, hi = cw.decode()
    clo, chi = cw.child_boxes()
    used = cw.kind != EMPTY
    wlo, whi = widen(clo[used], chi[used])
    assert (lo[used] <= wlo).all() and (hi[used] >= whi).all()          # the quantized box holds the float box
    tri = cw.bvh.triangles()
    for j in range(LEAF_TRIANGLES):                                      # which holds its triangles
        m = (cw.kind == LEAF) & (j < cw.tri_count)
        t = tri[cw.tri_slot[cw.tri_first[m] + j]]
        assert (lo[m] <= t.min(1)).all() and (hi[m] >= t.max(1)).all()
    p, s = np.nonzero(cw.kind == INTERNAL)                               # and its node's children
    c = cw.child[p, s]
    inner = cw.kind[c] != EMPTY
    assert (np.where(inner[..., None], clo[c], np.inf) >= lo[p, s][:, None]).all()
    assert (np.where(inner[..., None], chi[c], -np.inf) <= hi[p, s][:, None]).all()


def test_octant_order_places_children_by_corner_and_is_a_permutation():
    corners = np.array([[(s >> 2) & 1, (s >> 1) & 1, s & 1] for s in range(8)], np.float32) * 2 - 1
    rng = np.random.default_rng(1)
    order = np.stack([rng.permutation(8) for _ in range(5)])
    lo = (corners[order] - 0.3).astype(np.float32)
    hi = (corners[order] + 0.3).astype(np.float32)
    slot_of = octant_slots(lo, hi, np.ones((5, 8), bool))
    assert np.array_equal(slot_of, order)                 # the child at corner s goes to slot s
    used = rng.random((200, 8)) < 0.6
    c = rng.normal(size=(200, 8, 3)).astype(np.float32)
    slot_of = octant_slots(c - 0.1, c + 0.1, used)
    assert (np.sort(slot_of, axis=1) == np.arange(8)).all()
    cw = build_cwbvh(build_bvh(*soup(2000, seed=3)))
    # in the built tree, along +x the children of slots with bit 4 clear come first: their centres
    # lie at or below those of bit 4 set, on average
    lo, hi = cw.child_boxes()
    cx = 0.5 * (lo[..., 0] + hi[..., 0])
    both = (cw.kind[:, :4] != EMPTY).any(1) & (cw.kind[:, 4:] != EMPTY).any(1)
    low = np.where(cw.kind[:, :4] != EMPTY, cx[:, :4], np.nan)
    high = np.where(cw.kind[:, 4:] != EMPTY, cx[:, 4:], np.nan)
    assert (np.nanmean(low[both], 1) < np.nanmean(high[both], 1)).mean() > 0.9
    assert ray_octants([[1, -1, 1], [-1, 1, -1], [0, 0, -0.0]]).tolist() == [2, 5, 0]


def test_built_node_puts_the_child_at_each_corner_in_that_corners_slot():
    """Eight small triangles, one near each corner of a box about 2 x 8 x 4 (the binary build splits y,
    then z, then x: its children come in that order), given in a scrambled order: the built tree is
    one node of eight one-triangle leaves, and slot s holds the triangle at the corner of sign
    vector (s & 4: +x, s & 2: +y, s & 1: +z), the order in which a ray of octant bits o visits
    them, slot k ^ o (accel/cwbvh.py's module docstring). Fails if the build stores the children by
    the inverse of octant_slots' placement (from the binary order y z x to x y z: a 3-cycle of the
    bits, no involution), or in the binary order."""
    corners = np.array([[(s >> 2) & 1, (s >> 1) & 1, s & 1] for s in range(8)], np.float32) * 2 - 1
    order = np.array([3, 6, 0, 5, 7, 1, 4, 2])                  # input triangle i sits at corner order[i]
    tri = np.float32([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0.1]])
    v = (corners[order][:, None, :] * np.float32([0.9, 3.9, 1.9]) + tri[None]).reshape(-1, 3).astype(np.float32)
    bvh = build_bvh(v, np.arange(24).reshape(8, 3), max_leaf_size=1)
    cw = build_cwbvh(bvh)
    assert cw.node_count == 1 and (cw.kind[0] == LEAF).all() and (cw.tri_count[0] == 1).all()
    face = bvh.prim_ids[cw.tri_slot[cw.tri_first[0]]]            # the input triangle in each slot
    # (the binary tree's leaves, left to right, are corners y z x: slot (x y z) = its order's bits rotated)
    binary = order[bvh.prim_ids[bvh.start[bvh.left < 0]]]
    assert binary.tolist() == [((p & 1) << 2) | (p >> 1) for p in range(8)]
    assert order[face].tolist() == list(range(8))


@pytest.mark.parametrize("case", ["soup", "room"])
def test_numpy_walk_matches_binary_reference(case):
    name, v, f, o, d = next(c for c in cases() if c[0] == case)
    bvh = build_bvh(v, f)
    cw = build_cwbvh(bvh)
    prim, t, _, _ = trace_reference(bvh, o, d)
    assert 0.3 < (prim != MISS).mean()
    stats, ref_stats = {}, {}
    cp, ct, _, _ = trace_cwbvh_reference(cw, o, d, stats=stats)
    assert np.array_equal(cp, prim) and np.array_equal(ct, t)
    trace_reference(bvh, o, d, stats=ref_stats)
    assert stats["node_visits"].mean() < ref_stats["pair_node_visits"].mean()
    occ = trace_cwbvh_reference(cw, o, d, tmax=0.5, any_hit=True)
    assert np.array_equal(occ, trace_reference(bvh, o, d, tmax=0.5, any_hit=True))


def traces(gl, bvh, o, d, tmax, layouts=("bvh2", "cwbvh")):
    out = {}
    for layout in layouts:
        gb = GpuBvh(gl, bvh, layout=layout)
        rt = RayTracer(gl, gb)
        work = {}
        out[layout] = (rt.trace(o, d, tmax=tmax, work=work), rt.trace(o, d, tmax=tmax * 0.5, mode="any"), work)
        gb.release()
    return out


def assert_bitwise_bvh2(out):
    (ref, ref_any, _), (h, occ, _) = out["bvh2"], out["cwbvh"]
    assert np.array_equal(h.prim, ref.prim)
    for a, b in ((h.t, ref.t), (h.u, ref.u), (h.v, ref.v)):
        assert np.array_equal(a.view(np.uint32), b.view(np.uint32))
    assert np.array_equal(occ, ref_any)


@pytest.mark.parametrize("case,spatial", [("soup", False), ("room", False), ("soup", True)])
def test_gpu_cwbvh_returns_bvh2_hits_bit_for_bit(gl, case, spatial):
    """Also over an SBVH, whose triangles fill several slots (the copies name theirs)."""
    name, v, f, o, d = next(c for c in cases() if c[0] == case)
    bvh = build_bvh(v, f, spatial_splits=spatial, progress=False)
    assert (bvh.reference_count > bvh.triangle_count) == spatial
    out = traces(gl, bvh, o, d, np.float32(40.0))
    assert_bitwise_bvh2(out)
    h, _, work = out["cwbvh"]
    assert 0.3 < (h.prim != MISS).mean()
    stats = {}
    trace_cwbvh_reference(build_cwbvh(bvh), o, d, tmax=np.float32(40.0), stats=stats)
    # the GPU fetches the nodes the numpy walk does (its box test is a little wider)
    assert (work["node_visits"] >= stats["node_visits"]).mean() > 0.99
    assert abs(work["node_visits"].mean() / stats["node_visits"].mean() - 1) < 0.01
    assert work["node_visits"].mean() < out["bvh2"][2]["node_visits"].mean()


def test_gpu_cwbvh_axis_rays_edges_degenerate_rays_and_ties(gl):
    v, f = cube()
    o, d, inside = cube_edge_rays()
    out = traces(gl, build_bvh(v, f, max_leaf_size=1), o, d, np.float32(100.0))
    assert_bitwise_bvh2(out)
    h = out["cwbvh"][0]
    assert (h.prim[:len(inside)][inside] != MISS).all() and np.allclose(h.t[:len(inside)][inside], 4.0)
    assert h.prim[-4] != MISS and (h.prim[-3:] == MISS).all()
    # two triangles sharing an edge the rays go down onto: the lower ID, whichever is met first
    v = np.array([[0.5, -1, 0], [0.5, 1, 0], [1.5, 0, 0], [-0.5, 0, 1]], np.float32)
    y = np.linspace(-0.9, 0.9, 7, dtype=np.float32)
    o = np.stack([np.full_like(y, 0.5), y, np.full_like(y, 5.0)], 1)
    d = np.tile(np.float32([0, 0, -1]), (len(y), 1))
    for f in (np.array([[0, 1, 2], [0, 1, 3]]), np.array([[0, 1, 3], [0, 1, 2]])):
        bvh = build_bvh(v, f, max_leaf_size=1)
        assert (trace_cwbvh_reference(build_cwbvh(bvh), o, d)[0] == 0).all()
        assert (traces(gl, bvh, o, d, np.float32(100.0))["cwbvh"][0].prim == 0).all()


@pytest.mark.parametrize("offset", [0.0, 1e4])
def test_gpu_cwbvh_rays_from_a_nodes_quantization_origin_to_its_triangles_corners(gl, offset):
    """Rays that start at a node's quantization origin, where the box test's margin (relative to the
    origin's distance from the ray's) is nothing, aimed at the corners of the triangles in its leaf
    children (a corner lies on its child box's faces wherever it is the extreme), near the origin
    and 1e4 from it. The GPU's compressed wide BVH hits what bvh2 hits, bit for bit. (A far plane
    decoded 1e-6 short passes it too: the quantized boxes' outward rounding leaves these corners
    inside; test_gpu_cwbvh_rays_grazing_a_child_boxs_far_plane makes rays that graze one.)"""
    from rayvr.accel.cwbvh import NODE_VEC4

    v, f = soup(300, seed=7)
    v = (v + offset).astype(np.float32)
    bvh = build_bvh(v, f)
    cw = build_cwbvh(bvh)
    origin = unpack(cw.packed[:cw.node_count * NODE_VEC4].reshape(-1, NODE_WORDS))[0].astype(np.float64)
    tri = cw.bvh.triangles()
    o, d = [], []
    for n, s in zip(*np.nonzero(cw.kind == LEAF)):
        for j in range(int(cw.tri_count[n, s])):
            for corner in tri[cw.tri_slot[cw.tri_first[n, s] + j]]:
                o.append(origin[n])
                d.append(corner - origin[n])
    o, d = np.asarray(o, np.float32), np.asarray(d, np.float32)
    keep = np.linalg.norm(d, axis=1) > 1e-4 * np.ptp(v)  # a corner at the origin points nowhere
    out = traces(gl, bvh, o[keep], d[keep], np.float32(1e6))
    assert_bitwise_bvh2(out)
    assert keep.sum() > 500 and (out["bvh2"][0].prim != MISS).mean() > 0.9  # the rays meet what they aim at


GRID = 2.0 ** -7        # the quantum of grazing_scene's one node: its origin is (-1, -1, -1)
# Per grazing triangle, in quanta from the origin: its lower y face and its upper z face. The lines
# of sight from the origin, (y + 1) / (z + 1) ~ j / k, lie apart, so no triangle hides another.
GRAZING_PLANES = ((136, 144), (150, 176), (160, 184), (140, 200), (170, 190))


def grazing_scene():
    """One CWBVH node, origin (-1, -1, -1), quantum 2^-7 on every axis (three anchor triangles give
    its widened minimum exactly -1 and its maximum), and five triangles lying in planes z = c, each
    with an edge along y = y0, placed so that the quantized child box's lower y plane and upper z
    plane are their widened faces exactly: grid planes one ulp outside y0 and c. A ray through that
    edge enters the box by the y plane and leaves it by the z plane at the edge itself.
    Returns vertices, faces and per grazing triangle (face, x range of its edge, y0, c)."""
    f32 = np.float32
    below, above = f32(np.nextafter(f32(-1), f32(0))), f32(0.9)      # widened: -1 exactly
    tris = [[(below, above - .4, above), (below, above, above), (below, above, above - .4)],
            [(above - .4, below, above), (above, below, above), (above, below, above - .4)],
            [(above - .4, above, below), (above, above, below), (above, above - .4, below)]]
    grazing = []
    for i, (j, k) in enumerate(GRAZING_PLANES):
        y0 = np.nextafter(f32(-1 + j * GRID), f32(np.inf))             # its face widened: the grid plane
        c = np.nextafter(f32(-1 + k * GRID), f32(-np.inf))
        xa, xb = f32(0.1 + 0.02 * i), f32(0.5 + 0.02 * i)
        grazing.append((len(tris), xa, xb, y0, c))
        tris.append([(xa, y0, c), (xb, y0, c), (0.5 * (xa + xb), y0 + f32(0.01), c)])
    v = np.asarray(tris, np.float32).reshape(-1, 3)
    return v, np.arange(len(v)).reshape(-1, 3), grazing


def test_gpu_cwbvh_rays_grazing_a_child_boxs_far_plane(gl):
    """Rays through an edge that lies in two planes of its child's quantized box, the near y plane
    and the far z plane (grazing_scene): each passes through the box within 2.5e-7 of its distance
    (float64 on the decoded boxes; some, by exact arithmetic, just outside it, where the float32
    triangle test still hits). From the node's quantization origin (the box test's margin, relative
    to the origin's offset, is nothing), along directions scaled by random factors so that 1/d
    rounds both ways; and from 20 to 60 node widths behind the origin on the same lines of sight.
    bvh2 hits the aimed triangle at the analytic distance of its plane; the compressed layout returns
    bvh2's hits bit for bit. It fails if the far distance loses 1e-6 (t1 * (1 - 1e-6): the origin's
    rays miss), if the far plane's base is 1e-6 of it short after its margin (base - 2 * margin *
    |base|: the far rays miss), or if the 1.00000024 rounding factor is dropped (~100 rays, those
    whose box test float32 rounds closed: counted here in numpy)."""
    from rayvr.accel.cwbvh import NODE_VEC4

    f32 = np.float32
    v, f, grazing = grazing_scene()
    bvh = build_bvh(v, f, max_leaf_size=1)
    cw = build_cwbvh(bvh)
    nodes = cw.packed[:cw.node_count * NODE_VEC4].reshape(-1, NODE_WORDS)
    origin, ebias = unpack(nodes)[:2]
    assert cw.node_count == 1 and (cw.kind == LEAF).all() and (cw.tri_count == 1).all()
    assert (origin == -1).all() and (ebias - 127 == -7).all()
    lo, hi = (x[0] for x in cw.decode())
    face_of_slot = bvh.prim_ids[cw.tri_slot[cw.tri_first[0]]]
    rng = np.random.default_rng(0)
    o, d, aim, plane = [], [], [], []
    for face, xa, xb, y0, c in grazing:
        s = int(np.flatnonzero(face_of_slot == face)[0])
        assert lo[s, 1] == np.nextafter(y0, f32(-np.inf)) and hi[s, 2] == np.nextafter(c, f32(np.inf))
        x = rng.uniform(xa + 0.02, xb - 0.02, 400)
        q = np.stack([x.astype(np.float32), np.full_like(x, y0), np.full_like(x, c)], 1).astype(np.float64)
        scale = rng.uniform(0.5, 2.0, (len(x), 1))
        back = rng.uniform(20, 60, (len(x), 1))
        far = -1 - back * (q + 1) + rng.normal(size=q.shape) * 0.02 * back
        o += [np.full_like(q, -1.0), far]
        d += [(q + 1) * scale, q - far]
        aim += [np.full(2 * len(x), face)]
        plane += [np.full(2 * len(x), float(c))]
    n = sum(len(x) for x in aim) // 2
    o, d = np.asarray(np.concatenate(o), np.float32), np.asarray(np.concatenate(d), np.float32)
    aim, plane = np.concatenate(aim), np.concatenate(plane)
    from_origin = (o == -1).all(1)
    assert from_origin.sum() == n

    # They graze: the decoded child box holds a stretch of each ray at most 2.5e-7 of its distance.
    slot = np.array([np.flatnonzero(face_of_slot == a)[0] for a in aim])
    o64, d64 = o.astype(np.float64), d.astype(np.float64)
    ta, tb = (lo[slot] - o64) / d64, (hi[slot] - o64) / d64
    t_in, t_out = np.minimum(ta, tb).max(1), np.maximum(ta, tb).min(1)
    assert (np.abs(t_out - t_in) < 2.5e-7 * t_out).all()
    # An IEEE float32 box test from the origin without the rounding factor (what cwbvh.glsl
    # computes there: base 0, planes q * (scale * 1/d)) closes on some of them.
    inv = f32(1) / d
    q_lo, q_hi = np.round((lo + 1) / GRID).astype(np.float32), np.round((hi + 1) / GRID).astype(np.float32)
    t0, t1 = q_lo[slot] * (f32(GRID) * inv), q_hi[slot] * (f32(GRID) * inv)
    closed = from_origin & (np.maximum(t0.max(1), 0) > t1.min(1))

    out = traces(gl, bvh, o, d, np.float32(1e3))
    ref = out["bvh2"][0]
    hit = ref.prim != MISS
    for rays in (from_origin, ~from_origin):
        assert hit[rays].mean() > 0.7
    assert (ref.prim[hit] == aim[hit]).all()
    np.testing.assert_allclose(ref.t[hit], (plane - o64[:, 2])[hit] / d64[hit, 2], rtol=1e-6)
    assert closed.sum() > 50 and (closed & hit).sum() > 20, (closed.sum(), (closed & hit).sum())
    assert_bitwise_bvh2(out)


def test_gpu_cwbvh_empty_single_triangle_and_refit(gl):
    o = np.array([[0.2, 0.2, -1], [5, 5, -1]], np.float32)
    d = np.array([[0, 0, 1], [0, 0, 1]], np.float32)
    one = build_bvh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
    empty = build_bvh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    h = RayTracer(gl, GpuBvh(gl, one, layout="cwbvh")).trace(o, d)
    assert h.prim.tolist() == [0, MISS] and h.t[0] == pytest.approx(1.0)
    assert (RayTracer(gl, GpuBvh(gl, empty, layout="cwbvh")).trace(o, d).prim == MISS).all()
    assert not trace_cwbvh_reference(build_cwbvh(empty), o, d, any_hit=True).any()
    v, f = soup(600, seed=3)
    bvh = build_bvh(v, f)
    gb = GpuBvh(gl, bvh, layout="cwbvh")
    moved = (v * 1.3 + np.sin(v[:, [1, 2, 0]])).astype(np.float32)
    bvh.refit(moved)
    gb.update()
    o, d = rays_at(moved, 2000, seed=4)
    fresh = RayTracer(gl, GpuBvh(gl, build_bvh(moved, f))).trace(o, d)
    h = RayTracer(gl, gb).trace(o, d)
    assert np.array_equal(h.prim, fresh.prim) and np.array_equal(h.t, fresh.t)


def test_deep_tree_is_a_clear_error(gl, monkeypatch):
    from rayvr.accel import gpu
    monkeypatch.setattr(gpu, "CWBVH_STACK_ENTRIES", 1)
    with pytest.raises(ValueError, match="cwbvh: a traversal may hold .* stack entries, more than the GPU stack"):
        GpuBvh(gl, build_bvh(*soup(2000)), layout="cwbvh")


@pytest.mark.parametrize("materials", ["default_room.toml", "photon_room.toml", "path"])
def test_frame_through_cwbvh_is_bit_identical_to_bvh2(gl, materials):
    """The room with rayvr/assets/default_room.toml (shadows, glossy, mirror reflections), with
    photon_room.toml (photon paths) and path traced, every ray kind through the compressed layout:
    the binary layout's frame, bit for bit."""
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import Renderer, RenderSettings
    from rayvr.scene.loader import load
    from rayvr.scene.materials import load_config
    from rayvr.accel.gpu import parse_traversal
    assert parse_traversal("cwbvh") == ("cwbvh",) * 3
    scene = load()
    rig = StereoRig.for_scene(scene, size=(40, 30))
    from rayvr.scene.materials import parse_config
    config = parse_config({"default": "path"}, "test") if materials == "path" else \
        load_config(f"rayvr/assets/{materials}")
    frames = {}
    for layout in ("bvh2", "cwbvh"):
        r = Renderer(scene, config, gl=gl, settings=RenderSettings(primary="rays", traversal=layout))
        try:
            frames[layout] = r.render(rig, aux=("triangle", "hdr"))
            if layout == "cwbvh":
                assert set(r.accel.wide) == {"cwbvh"}
        finally:
            r.release()
    for eye in ("left", "right"):
        a, b = frames["bvh2"].eyes[eye], frames["cwbvh"].eyes[eye]
        assert np.array_equal(a.color, b.color) and np.array_equal(a.depth, b.depth)
        for k in ("triangle", "hdr"):
            assert np.array_equal(a.aux[k].view(np.uint8), b.aux[k].view(np.uint8))
    assert (frames["bvh2"].left.aux["triangle"] != MISS).mean() > 0.5
    traced = {"default_room.toml": {"rt_shadows", "rt_glossy", "rt_reflections"},
              "photon_room.toml": {"photon_trace", "rt_photon"}, "path": {"rt_path"}}[materials]
    assert traced <= set(frames["cwbvh"].passes)


def test_capture_with_traversal_cwbvh_writes_the_bvh2_images(tmp_path):
    """`rayvr capture --traversal cwbvh` (ray-cast primary, the room's default_room.toml): the
    same PNGs, pixel for pixel, as --traversal bvh2."""
    from PIL import Image
    from conftest import run_rayvr
    common = ("capture", "--materials", "rayvr/assets/default_room.toml", "--size", "32x24", "--primary", "rays", "-q")
    images = {}
    for layout in ("bvh2", "cwbvh"):
        run = run_rayvr(*common, "--traversal", layout, "--out", tmp_path / layout)
        assert run.returncode == 0, run.stderr
        images[layout] = [np.asarray(Image.open(tmp_path / layout / f"frame_{eye}.png")) for eye in ("left", "right")]
    for a, b in zip(images["bvh2"], images["cwbvh"]):
        assert a.shape == b.shape and np.array_equal(a, b) and a.std() > 5
