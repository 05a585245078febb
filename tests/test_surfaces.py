"""Smooth surfaces (rayvr/scene/surfaces.py) and the MSAA merge by surface (shading_merge "surface",
the default) against the merge by triangle (the reference): meshes whose surfaces are known, a
breadth-first walk over trimesh's own face adjacency, and frames of the room."""
from __future__ import annotations

from collections import deque

import numpy as np
import pytest
import trimesh

from rayvr import Renderer
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.options import OptionError
from rayvr.renderer import RenderSettings
from rayvr.scene.loader import load
from rayvr.scene.surfaces import SMOOTH_ANGLE_DEG, connected_labels, surface_groups


def groups(mesh, material=None):
    material = np.zeros(len(mesh.faces), np.uint32) if material is None else material
    return surface_groups(np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.uint32), material)


def unwelded(mesh):
    """The mesh with its own three vertices a triangle (as a loader splits UV seams and flat normals)."""
    return trimesh.Trimesh(mesh.vertices[mesh.faces].reshape(-1, 3), np.arange(3 * len(mesh.faces)).reshape(-1, 3),
                           process=False)


@pytest.mark.parametrize("mesh, surfaces", [
    (trimesh.creation.icosphere(3), 1), (trimesh.creation.box(), 6), (trimesh.creation.cylinder(0.5, 1, 64), 3),
    (trimesh.creation.torus(1.0, 0.3, 48, 24), 1)], ids=["sphere", "box", "cylinder", "torus"])
def test_known_meshes_have_their_smooth_surfaces(mesh, surfaces):
    for m in (mesh, unwelded(mesh)):  # welded by position: split vertices do not split a surface
        g = groups(m)
        assert len(np.unique(g)) == surfaces and g.dtype == np.uint32
        assert set(np.unique(g)) == set(range(surfaces))  # IDs 0..S-1


def test_materials_and_creases_split_surfaces():
    sphere = trimesh.creation.icosphere(2)
    half = (sphere.triangles_center[:, 0] > 0).astype(np.uint32)
    g = groups(sphere, half)
    assert len(np.unique(g)) == 2 and (g[half == 0][0] != g[half == 1][0])
    # a 20-sided prism's sides meet at 18 degrees: one surface below the 30-degree crease, not at 10
    prism = trimesh.creation.cylinder(0.5, 1, 20)
    assert len(np.unique(groups(prism))) == 3
    coarse = surface_groups(np.asarray(prism.vertices, np.float32), prism.faces, np.zeros(len(prism.faces)),
                            max_angle_deg=10.0)
    assert len(np.unique(coarse)) == 22


def test_split_normals_keep_a_smooth_looking_mesh_apart():
    """A sphere shaded flat (each triangle's own normal at its corners, as a loader gives faceted
    geometry) is one surface per triangle; its own smooth vertex normals make it one surface again."""
    sphere = unwelded(trimesh.creation.icosphere(2))
    tris = len(sphere.faces)
    vertices, faces, material = np.asarray(sphere.vertices, np.float32), sphere.faces, np.zeros(tris)
    flat = np.repeat(sphere.face_normals, 3, axis=0)
    assert len(np.unique(surface_groups(vertices, faces, material, flat))) == tris
    smooth = vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    assert len(np.unique(surface_groups(vertices, faces, material, smooth))) == 1


def bfs_groups(mesh, max_deg):
    """An independent walk: trimesh's face adjacency and angles, breadth first."""
    n = len(mesh.faces)
    near = [[] for _ in range(n)]
    for (a, b), angle in zip(mesh.face_adjacency, mesh.face_adjacency_angles):
        if np.degrees(angle) < max_deg:
            near[a].append(b)
            near[b].append(a)
    label = np.full(n, -1)
    for start in range(n):
        if label[start] >= 0:
            continue
        label[start] = start
        queue = deque([start])
        while queue:
            f = queue.popleft()
            for o in near[f]:
                if label[o] < 0:
                    label[o] = start
                    queue.append(o)
    return label


def test_surfaces_match_a_breadth_first_walk_of_a_bumpy_sphere():
    rng = np.random.default_rng(3)
    sphere = trimesh.creation.icosphere(3)
    bumpy = trimesh.Trimesh(sphere.vertices * (1 + 0.12 * rng.random((len(sphere.vertices), 1))), sphere.faces)
    mine, theirs = groups(bumpy), bfs_groups(bumpy, SMOOTH_ANGLE_DEG)
    assert 5 < len(np.unique(theirs)) < len(bumpy.faces) // 2  # creases above and below 30 degrees
    # the same partition: a one-to-one map between the two labellings
    pairs = np.unique(np.stack([mine, theirs], 1), axis=0)
    assert len(pairs) == len(np.unique(mine)) == len(np.unique(theirs))


def test_connected_labels_of_a_long_chain_and_isolated_nodes():
    chain = np.stack([np.arange(999, 0, -1), np.arange(998, -1, -1)], 1)  # 999-998, ..., 1-0
    assert (connected_labels(1002, chain) == [0] * 1000 + [1000, 1001]).all()


ROOM_POSE = Pose.look_at([0.3, 1.5, 1.0], [0.9, 0.9, -1.4])  # the mirror sphere and gold torus in view


@pytest.fixture(scope="module")
def room():
    return load(None)


def room_frame(gl, room, merge, size=(96, 64), **settings):
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=size, near=1e-3, camera=Distorted())
    with Renderer(room, gl=gl, settings=RenderSettings(primary="rays", msaa=4, seed=9, shading_merge=merge,
                                                       **settings)) as r:
        fc = r.record(rig)
        r.gl.ctx.finish()
        rounds = len(r.read_round_ms(fc).get("sample_accumulate", []))
        out = r.render(rig)
        slots = r.plan(camera=rig.camera)
        hits = np.frombuffer(r.resource("msaa_hits").read(), np.uint32)
    counts = ((hits.reshape(-1, 2, size[1], size[0], 4)[0, ..., 2] >> 8) & 255)[:, ::-1]
    color = np.stack([np.asarray(out.left.color), np.asarray(out.right.color)])[..., :3].astype(np.float64)
    return color, counts, rounds


def test_merging_by_surface_shades_fewer_entries_and_keeps_the_image(gl, room):
    surface, s_counts, s_rounds = room_frame(gl, room, "surface")
    triangle, t_counts, t_rounds = room_frame(gl, room, "triangle")
    assert (s_counts <= t_counts).all() and s_counts.sum() < t_counts.sum()
    assert s_rounds < t_rounds
    one = t_counts == 1  # a pixel on one triangle is one entry either way: the same, to the bit
    assert one.mean() > 0.6
    np.testing.assert_array_equal(surface[one], triangle[one])
    merged = s_counts < t_counts
    assert merged.sum() >= 20
    # where triangles merged, the pixel is shaded at fewer points of the same smooth surface: close
    diff = np.abs(surface[merged] - triangle[merged]).mean()
    assert diff < 6.0, diff  # 8-bit levels; a wrong entry (background, the wrong side) is tens
    assert np.abs(surface - triangle).mean() < 0.5


def test_shading_merge_is_checked():
    with pytest.raises(OptionError, match="shading merge"):
        RenderSettings(shading_merge="object")
