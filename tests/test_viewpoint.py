"""A scene's first view (rayvr/app/viewpoint.py): inside a scene that encloses its centre, at eye
height over its floor and gazing at its content; from outside a closed object or an open box;
the file's own camera first. Judged by geometry: the pose's place against the box, and a ray along
its view axis against the triangles it must meet."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import merge, quad, run_rayvr
from rayvr.accel.bvh import build_bvh, trace_reference
from rayvr.app.viewpoint import EYE_HEIGHT, SceneView, first_rig, first_view, pose_argument
from rayvr.scene.loader import Material, from_arrays

ROOM_WALLS = [  # an 8 x 3.2 x 8 m box, every face towards the inside
    quad((0, 0, 0), (4, 0, 0), (0, 0, -4)), quad((0, 3.2, 0), (4, 0, 0), (0, 0, 4)),
    quad((0, 1.6, -4), (4, 0, 0), (0, 1.6, 0)), quad((0, 1.6, 4), (-4, 0, 0), (0, 1.6, 0)),
    quad((-4, 1.6, 0), (0, 0, -4), (0, 1.6, 0)), quad((4, 1.6, 0), (0, 0, 4), (0, 1.6, 0))]


def cube(c, h):
    """A closed cube of half-size h at c, every face outwards."""
    c = np.asarray(c, float)
    return [quad(c + (h, 0, 0), (0, 0, -h), (0, h, 0)), quad(c - (h, 0, 0), (0, 0, h), (0, h, 0)),
            quad(c + (0, h, 0), (h, 0, 0), (0, 0, -h)), quad(c - (0, h, 0), (h, 0, 0), (0, 0, h)),
            quad(c + (0, 0, h), (h, 0, 0), (0, h, 0)), quad(c - (0, 0, h), (-h, 0, 0), (0, h, 0))]


def scene_of(parts, name="t"):
    v, f, part = merge(*parts)
    walls = len(parts) - 6 if len(parts) > 6 else 0
    material = np.where(part < walls, 0, 1)
    return from_arrays(v, f, triangle_material=material, materials=[Material("wall"), Material("box")], name=name)


def view_axis_hits(scene, pose) -> int:
    """The triangle the pose's view axis meets first (-1: none)."""
    bvh = build_bvh(scene.vertices, scene.indices)
    prim, t, _, _ = trace_reference(bvh, (pose.position - scene.origin)[None], pose.forward[None])
    return int(prim[0]) if np.isfinite(t[0]) else -1


def test_a_room_is_seen_from_inside_at_eye_height_gazing_at_its_content():
    room = scene_of(ROOM_WALLS + cube((2.0, 0.5, -1.5), 0.5))
    view = SceneView(room)
    met, facing = view.enclosed_shares
    assert met == 1.0 and facing == 1.0 and view.encloses()
    how, pose = first_view(room)
    assert how == "inside"
    np.testing.assert_allclose(pose.position, (0.0, EYE_HEIGHT, 0.0), atol=1e-9)  # over the floor below the centre
    hit = view_axis_hits(room, pose)
    assert hit >= 12 and room.triangle_material[hit] == 1  # the axis meets the box, not a wall
    rig = first_rig(room, (32, 24))
    assert rig.pose.position.tolist() == pose.position.tolist()


@pytest.mark.parametrize("parts, why", [
    (cube((0.0, 0.0, 0.0), 1.0), "a closed object: from its centre every face faces away"),
    ([(v, f[:, ::-1]) for v, f in cube((0.0, 0.0, 0.0), 1.0)[:5]],  # faces inwards, its +z side open
     "inside a cube open on one side (a Cornell box): a sixth of the rays escape"),
], ids=["object", "open_box"])
def test_an_object_or_an_open_box_is_seen_from_outside(parts, why):
    scene = scene_of(parts)
    view = SceneView(scene)
    assert not view.encloses(), why
    met, facing = view.enclosed_shares
    assert (met, facing) == ((1.0, 0.0) if len(parts) == 6 else (met, met)) and (len(parts) == 6 or met < 0.9)
    how, pose = first_view(scene)
    assert how == "outside" and pose is None
    lo, hi = (np.asarray(b) for b in scene.bounds)
    position = first_rig(scene, (32, 24)).pose.position
    assert not (np.all(position > lo) and np.all(position < hi))  # the framing view stands outside the bounds


def test_the_files_own_camera_comes_first():
    from rayvr.scene.loader import load

    room = load(None)  # the built-in room has a camera
    assert first_view(room) == ("its camera", None)


def test_pose_argument_is_what_pose_takes():
    room = scene_of(ROOM_WALLS + cube((2.0, 0.5, -1.5), 0.5))
    _, pose = first_view(room)
    e = np.array([float(x) for x in pose_argument(pose).split(",")])
    np.testing.assert_allclose(e[:3], pose.position, atol=1e-3)
    np.testing.assert_allclose(e[3:] - e[:3], pose.forward, atol=1e-3)


def test_sponza_opens_in_its_nave(shared_scene):
    from rayvr.bench.scenes import SCENES
    from rayvr.scene import loader
    from rayvr.scene.content import content_triangles

    sponza = loader.load(shared_scene(SCENES["sponza"][0]))
    how, pose = first_view(sponza)
    assert how == "inside"
    lo, hi = (np.asarray(b) for b in sponza.bounds)
    assert np.all(pose.position > lo) and np.all(pose.position < hi)
    hit = view_axis_hits(sponza, pose)
    assert hit >= 0 and content_triangles(sponza)[hit]  # a pillar or an arch, not the floor or a wall


def test_cli_logs_the_first_view_and_info_names_it(tmp_path):
    import trimesh

    room = scene_of(ROOM_WALLS + cube((2.0, 0.5, -1.5), 0.5))
    path = tmp_path / "room.obj"
    trimesh.Trimesh(room.vertices, room.indices, process=False).export(path)
    r = run_rayvr("-v", "capture", str(path), "--size", "16x12", "--out", str(tmp_path / "out"), "--ambient", "0.2,0.2,0.2")
    assert r.returncode == 0, r.stderr
    logged = next(line for line in r.stderr.splitlines() if "first view (inside): --pose " in line)
    head = [float(x) for x in logged.split("--pose ")[1].split(",")][:3]
    floor = trimesh.load(path, process=False).bounds[0][1]  # (the loader may move the file's origin)
    np.testing.assert_allclose(head, (0.0, floor + EYE_HEIGHT, 0.0), atol=1e-3)
    info = run_rayvr("info", str(path))
    assert info.returncode == 0 and "encloses its centre: yes" in info.stdout and "first view inside" in info.stdout
