"""A scene's smooth surfaces: the triangles that MSAA shades as one where a pixel sees several of
them (rayvr/frame/passes/primary_rays.py, shading_merge "surface").

A surface is a set of triangles joined through shared edges (vertices welded by position, so a
UV seam does not split it) of one material, shaded smooth across each edge (the same shading
normal on both sides at its ends) and whose geometric normals differ by less than
SMOOTH_ANGLE_DEG: a tessellated sphere or torus is one surface, a box six (its
90-degree creases split it), two objects of different materials two. Triangles of one surface
seen at different depths in one pixel (a torus in front of its own far side) are told apart by
the merge itself, not here. Computed from the geometry as loaded: a mesh animated afterwards
keeps the surfaces of its first pose."""
from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from ..util.digest import arrays_digest

# The crease angle below which two triangles across an edge are one smooth surface (the common
# auto-smooth default of modelling tools; a 64-segment sphere's neighbours differ by 5.6 degrees).
SMOOTH_ANGLE_DEG = 30.0
SAME_NORMAL_DEG = 1.0  # two shading normals at one welded vertex this close are one smooth normal
KEPT = 4  # surfaces of the last few geometries (benchmarks make a Renderer per variant of one scene)
_kept: OrderedDict = OrderedDict()


def edge_neighbours(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(E, 2, 3) for each pair of triangles sharing an edge (vertices welded by exact position): the
    two triangles, and the original vertex IDs of the edge's two ends in each of them (the same
    welded vertex first). An edge of more than two triangles joins each to the next in the order of
    their IDs."""
    _, weld = np.unique(np.asarray(positions, np.float64), axis=0, return_inverse=True)
    indices = np.asarray(indices, np.int64)
    corners = weld.reshape(-1)[indices]  # (T, 3) welded vertex IDs
    sides = ([0, 1], [1, 2], [2, 0])
    edges = np.stack([corners[:, s] for s in sides], 1).reshape(-1, 2)
    ends = np.stack([indices[:, s] for s in sides], 1).reshape(-1, 2)
    swap = edges[:, 0] > edges[:, 1]  # each edge's welded ends in increasing order, its own ends alike
    edges[swap], ends[swap] = edges[swap][:, ::-1], ends[swap][:, ::-1]
    face = np.repeat(np.arange(len(corners)), 3)
    order = np.lexsort((face, edges[:, 1], edges[:, 0]))
    edges, ends, face = edges[order], ends[order], face[order]
    same = (edges[1:] == edges[:-1]).all(1) & (face[1:] != face[:-1])
    return np.stack([np.stack([face[:-1][same], ends[:-1][same][:, 0], ends[:-1][same][:, 1]], 1),
                     np.stack([face[1:][same], ends[1:][same][:, 0], ends[1:][same][:, 1]], 1)], 1)


def connected_labels(count: int, pairs: np.ndarray) -> np.ndarray:
    """Per node of `count`, the smallest node ID of its connected component over the edges `pairs`
    (hooking each edge's roots to the smaller, then halving the paths, until no edge spans two)."""
    label = np.arange(count)
    a, b = pairs[:, 0], pairs[:, 1]
    while True:
        la, lb = label[a], label[b]
        split = la != lb
        if not split.any():
            return label
        lo = np.minimum(la[split], lb[split])
        np.minimum.at(label, la[split], lo)
        np.minimum.at(label, lb[split], lo)
        while True:  # point every node at its root
            up = label[label]
            if (up == label).all():
                break
            label = up


def surface_groups(positions: np.ndarray, indices: np.ndarray, triangle_material: np.ndarray,
                   normals: np.ndarray | None = None, max_angle_deg: float = SMOOTH_ANGLE_DEG) -> np.ndarray:
    """Per triangle, the ID (0..S-1, uint32) of its smooth surface (the module's docstring). With
    the vertices' shading `normals`, an edge joins only where both triangles' normals at its two
    ends agree (within SAME_NORMAL_DEG): a hard edge (split normals, as flat-shaded faces have)
    keeps its sides apart whatever its angle."""
    indices = np.asarray(indices).reshape(-1, 3)
    if len(indices) == 0:
        return np.zeros(0, np.uint32)
    key = arrays_digest(positions, indices, triangle_material, np.zeros(0) if normals is None else normals,
                  np.float64(max_angle_deg))
    if key in _kept:
        _kept.move_to_end(key)
        return _kept[key]
    p = np.asarray(positions, np.float64)[indices]
    normal = _unit(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    pairs = edge_neighbours(positions, indices)
    a, b = pairs[:, 0, 0], pairs[:, 1, 0]
    material = np.asarray(triangle_material)
    smooth = ((normal[a] * normal[b]).sum(1) >= math.cos(math.radians(max_angle_deg))) & (material[a] == material[b])
    if normals is not None:
        n = _unit(np.asarray(normals, np.float64))
        agree = math.cos(math.radians(SAME_NORMAL_DEG))
        for end in (1, 2):
            smooth &= (n[pairs[:, 0, end]] * n[pairs[:, 1, end]]).sum(1) >= agree
    _, groups = np.unique(connected_labels(len(indices), pairs[smooth][:, :, 0]), return_inverse=True)
    groups = groups.reshape(-1).astype(np.uint32)
    _kept[key] = groups
    while len(_kept) > KEPT:
        _kept.popitem(last=False)
    return groups


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]
