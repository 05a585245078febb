"""The benches' head poses (rayvr/bench/head_poses.py): the shell classifier on the built-in room
(and Sponza where the shared scenes are), content poses that gaze at something visible, random
poses as before, and a render whose centre shows the content."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rayvr.bench import head_poses as H
from rayvr.scene import content as scene_content

SHELL = {"walls", "wall_green", "wall_red", "floor", "ceiling"}  # the room's enclosing box (default_room.toml)
CONTENT = {"glass", "box_blue", "box_white", "gold", "mirror_panel", "mirror"}  # its objects ("light": an emitter)


@pytest.fixture(scope="module")
def scene():
    from rayvr.scene import loader

    return loader.load(None)


@pytest.fixture(scope="module")
def poses(scene):
    return H.draw_poses(scene, "default", 20, 22)


def _material_names(scene, mask) -> set:
    names = scene.material_names()
    return {names[m] for m in np.unique(scene.triangle_material[mask])}


def test_the_room_s_walls_floor_and_ceiling_are_shell_and_its_objects_content(scene):
    assert set(scene.material_names()) == SHELL | CONTENT | {"light"}  # the test knows every material
    shell = scene_content.shell_triangles(scene)
    names = np.array(scene.material_names())[scene.triangle_material]
    assert shell[np.isin(names, sorted(SHELL))].all()
    assert not shell[np.isin(names, sorted(CONTENT | {"light"}))].any()  # the mirror panel 2 cm off its wall too
    content = scene_content.content_triangles(scene)
    assert _material_names(scene, content) == CONTENT  # the light is neither shell nor a target


def test_sponza_s_floors_and_big_walls_are_shell_and_its_pillars_and_arches_content(shared_scene):
    from rayvr.bench.scenes import SCENES
    from rayvr.scene import loader

    sponza = loader.load(shared_scene(SCENES["sponza"][0]))
    shell = scene_content.shell_triangles(sponza)
    names = np.array(sponza.material_names())[sponza.triangle_material]
    _, _, area = scene_content.triangles(sponza)
    for m in ("floors", "outside01"):
        assert shell[names == m].all(), m
    walls = names == "walls"
    assert area[walls & shell].sum() > 0.9 * area[walls].sum()
    for m in ("pillar_round", "arcs_01", "arcs_02", "relief", "ceiling"):  # curved or small: content
        assert not shell[names == m].any(), m


def _forward(yaw_deg, pitch_deg) -> np.ndarray:
    """head_rotation's view axis written out: yaw 0 along -Z, positive to the left (towards -X), pitch up."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    return np.array([-math.sin(y) * math.cos(p), math.sin(p), -math.cos(y) * math.cos(p)])


def _pixel_of(rig, eye: str, point) -> tuple[float, float]:
    """Where `point` lands in `eye`'s image (pixels, top-down rows, centres at .5): a pinhole of the
    rig's vertical fov, the eyes ipd / 2 to each side along the head's right axis."""
    r = rig.pose.rotation
    offset = {"left": -0.5, "right": 0.5, "center": 0.0}[eye] * rig.ipd
    p = r.T @ (np.asarray(point) - (rig.pose.position + offset * r[:, 0]))
    assert p[2] < 0  # in front
    w, h = rig.size
    t = math.tan(math.radians(rig.fov_y) / 2)
    x, y = p[0] / -p[2] / (t * w / h), p[1] / -p[2] / t
    return (x * 0.5 + 0.5) * w, (0.5 - y * 0.5) * h


def test_content_poses_gaze_at_their_target_from_far_enough(scene, poses):
    from rayvr.frame.cameras.rig import StereoRig

    content = [p for p in poses if p.kind == "content"]
    assert [p.index for p in content] == list(range(0, 20, 2))
    for p in content:
        d = np.asarray(p.target) - np.asarray(p.position)
        dist = np.linalg.norm(d)
        assert dist >= H.MIN_TARGET_M
        assert abs(p.pitch_deg) <= H.MAX_GAZE_PITCH_DEG and 0.0 <= p.yaw_deg < 360.0
        np.testing.assert_allclose(_forward(p.yaw_deg, p.pitch_deg), d / dist, atol=1e-9)
        rig = StereoRig(p.pose, size=(65, 49), fov_y=90.0)
        assert _pixel_of(rig, "center", p.target) == pytest.approx((32.5, 24.5), abs=1e-6)
        parallax = 0.5 * rig.ipd / dist * 24.5 / math.tan(math.radians(45))  # pixels, the eyes' half baseline
        for eye, side in (("left", 1.0), ("right", -1.0)):  # each eye sees it off centre by its parallax alone
            assert _pixel_of(rig, eye, p.target) == pytest.approx((32.5 + side * parallax, 24.5), abs=1e-6)
    assert len({p.kind for p in poses}) == 2


def _first_hits(scene, origins, directions) -> np.ndarray:
    """Distance to the nearest triangle along each ray: every ray against every triangle (Möller-Trumbore)."""
    tri = scene.world_vertices()[scene.indices]
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    out = []
    for o, d in zip(origins, directions):
        pv = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, pv)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = o - v0
            u = np.einsum("ij,ij->i", tv, pv) * inv
            qv = np.cross(tv, e1)
            v = (qv @ d) * inv
            t = np.einsum("ij,ij->i", e2, qv) * inv
        hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        out.append(t[hit].min() if hit.any() else np.inf)
    return np.array(out)


def test_nothing_stands_between_a_content_pose_and_its_target(scene, poses):
    content = [p for p in poses if p.kind == "content"]
    o = np.array([p.position for p in content])
    d = np.array([_forward(p.yaw_deg, p.pitch_deg) for p in content])
    dist = np.linalg.norm(np.array([p.target for p in content]) - o, axis=1)
    np.testing.assert_allclose(_first_hits(scene, o, d), dist, rtol=1e-6, atol=1e-5)


def test_embree_sees_the_target_first_too(scene, poses):
    pytest.importorskip("embreex", reason="embreex (an optional reference) is not installed")
    from embreex import mesh_construction, rtcore_scene

    es = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(es, scene.world_vertices().astype(np.float32), scene.indices.astype(np.int32))
    content = [p for p in poses if p.kind == "content"]
    o = np.array([p.position for p in content], np.float32)
    d = np.array([_forward(p.yaw_deg, p.pitch_deg) for p in content], np.float32)
    dist = np.linalg.norm(np.array([p.target for p in content]) - o, axis=1)
    hit = es.run(o, d, output=1)
    assert (hit["geomID"] != -1).all()
    np.testing.assert_allclose(hit["tfar"], dist, rtol=1e-4, atol=1e-4)
    names = np.array(scene.material_names())[scene.triangle_material[hit["primID"]]]
    assert set(names) <= CONTENT


def test_pose_i_does_not_depend_on_the_count(scene):
    few, many = H.draw_poses(scene, "default", 8, 22), H.draw_poses(scene, "default", 20, 22)
    assert many[:8] == few
    assert H.draw_poses(scene, "default", 1, 22) == few[:1]
    assert H.draw_poses(scene, "default", 8, 23) != few


def test_random_poses_are_the_older_scheme_s_draws_over_the_whole_turn_and_within_20_degrees(scene):
    import zlib

    poses = H.draw_poses(scene, "default", 400, 22)
    random = [p for p in poses if p.kind == "random"]
    assert [p.index for p in random] == list(range(1, 400, 2)) and all(p.target is None for p in random)
    # random pose k is pose k of the draws before content poses came: five uniforms each
    rng = np.random.default_rng([22, zlib.crc32(b"default")])
    bounds = H.pose_bounds(scene, "default")
    for p in random:
        old = [rng.uniform(*bounds[a]) for a in "xyz"] + [rng.uniform(0.0, 360.0), rng.uniform(-20.0, 20.0)]
        assert [*p.position, p.yaw_deg, p.pitch_deg] == old
    yaws, pitches = np.array([p.yaw_deg for p in random]), np.array([p.pitch_deg for p in random])
    assert 0.0 <= yaws.min() < 10.0 and 350.0 < yaws.max() < 360.0  # the whole turn, not half of it
    assert -20.0 <= pitches.min() < -18.0 and 18.0 < pitches.max() <= 20.0  # +-20, not +-10 nor +-60
    assert H.MAX_PITCH_DEG == 20.0


def test_a_scene_without_content_is_refused_in_one_line():
    from rayvr.scene import loader

    from conftest import quad, merge

    box = [quad((0, 0, 0), (4, 0, 0), (0, 0, -4)), quad((0, 3, 0), (4, 0, 0), (0, 0, 4))]
    v, f, _ = merge(*box)
    bare = loader.from_arrays(v, f, name="bare")
    with pytest.raises(ValueError, match="no content to gaze at"):
        H.draw_poses(bare, "default", 1, 22)


def test_a_content_pose_s_centre_pixel_shows_content(gl, scene, poses):
    """A render of each content pose (65 x 49 an eye, the eyes together so the centre pixel's ray is
    the gaze): the centre pixel's material is one of the room's objects."""
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import Renderer

    names = scene.material_names()
    with Renderer(scene, gl=gl) as r:
        for p in (p for p in poses if p.kind == "content"):
            rig = StereoRig(p.pose, ipd=0.0, size=(65, 49), near=0.05)
            f = r.render(rig, aux=("material",))
            for eye in (f.left, f.right):
                m = int(eye.aux["material"][24, 32])
                assert m < len(names) and names[m] in CONTENT, (p, m)
