"""A scene's smooth surfaces: the triangles that MSAA shades as one where a pixel sees several of
them (rayvr/frame/passes/primary_rays.py, shading_merge "surface").

A surface is a set of triangles joined through shared edges (vertices welded by position, so a
UV seam does not split it) of one material whose geometric normals differ by less than
SMOOTH_ANGLE_DEG across each edge: a tessellated sphere or torus is one surface, a box six (its
90-degree creases split it), two objects of different materials two. Triangles of one surface
seen at different depths in one pixel (a torus in front of its own far side) are told apart by
the merge itself, not here. Computed from the geometry as loaded: a mesh animated afterwards
keeps the surfaces of its first pose."""
from __future__ import annotations

import hashlib
import math
from collections import OrderedDict

import numpy as np

# The crease angle below which two triangles across an edge are one smooth surface (the common
# auto-smooth default of modelling tools; a 64-segment sphere's neighbours differ by 5.6 degrees).
SMOOTH_ANGLE_DEG = 30.0
KEPT = 4  # surfaces of the last few geometries (benchmarks make a Renderer per variant of one scene)
_kept: OrderedDict = OrderedDict()


def _digest(*arrays) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()


def edge_neighbours(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(E, 2) pairs of triangles that share an edge, vertices welded by exact position. An edge of
    more than two triangles joins each to the next in the order of their IDs."""
    _, weld = np.unique(np.asarray(positions, np.float64), axis=0, return_inverse=True)
    corners = weld.reshape(-1)[np.asarray(indices, np.int64)]  # (T, 3) welded vertex IDs
    edges = np.stack([corners[:, [0, 1]], corners[:, [1, 2]], corners[:, [2, 0]]], 1).reshape(-1, 2)
    edges.sort(axis=1)
    face = np.repeat(np.arange(len(corners)), 3)
    order = np.lexsort((face, edges[:, 1], edges[:, 0]))
    edges, face = edges[order], face[order]
    same = (edges[1:] == edges[:-1]).all(1) & (face[1:] != face[:-1])
    return np.stack([face[:-1][same], face[1:][same]], 1)


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
                   max_angle_deg: float = SMOOTH_ANGLE_DEG) -> np.ndarray:
    """Per triangle, the ID (0..S-1, uint32) of its smooth surface (the module's docstring)."""
    indices = np.asarray(indices).reshape(-1, 3)
    if len(indices) == 0:
        return np.zeros(0, np.uint32)
    key = _digest(positions, indices, triangle_material, np.float64(max_angle_deg))
    if key in _kept:
        _kept.move_to_end(key)
        return _kept[key]
    p = np.asarray(positions, np.float64)[indices]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    pairs = edge_neighbours(positions, indices)
    a, b = pairs[:, 0], pairs[:, 1]
    material = np.asarray(triangle_material)
    smooth = ((normal[a] * normal[b]).sum(1) >= math.cos(math.radians(max_angle_deg))) & (material[a] == material[b])
    _, groups = np.unique(connected_labels(len(indices), pairs[smooth]), return_inverse=True)
    groups = groups.reshape(-1).astype(np.uint32)
    _kept[key] = groups
    while len(_kept) > KEPT:
        _kept.popitem(last=False)
    return groups
