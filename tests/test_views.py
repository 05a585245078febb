"""Multi-view captures (rayvr/app/views.py): view files and generated views, and the transforms.json
NeRF / 3D Gaussian splatting tools read, checked by back-projecting the depth files through it
with plain pinhole maths against the world positions rayvr wrote."""
import json
import math

import numpy as np
import pytest

from conftest import run_rayvr
from rayvr.frame.cameras.rig import Pose
from rayvr.app.views import grid_views, load_views, sphere_views, views_for


rayvr = run_rayvr  # the CLI in a child process (conftest)


def back_project(frame, top, out, u, v):
    """World point of pixel (u, v) from transforms.json alone: OpenGL camera axes, linear depth."""
    k = {key: frame.get(key, top.get(key)) for key in ("fl_x", "fl_y", "cx", "cy")}
    depth = np.load(out / frame["depth_file_path"])[v, u]
    x = (u + 0.5 - k["cx"]) / k["fl_x"] * depth
    y = -(v + 0.5 - k["cy"]) / k["fl_y"] * depth  # rows go down, camera +Y goes up
    c2w = np.asarray(frame["transform_matrix"])
    return (c2w @ [x, y, -depth, 1.0])[:3]


def check_transforms(out, n_images):
    t = json.loads((out / "transforms.json").read_text())
    assert len(t["frames"]) == n_images
    for frame in t["frames"]:
        stem = out / frame["file_path"]
        assert stem.with_suffix(".png").exists()  # NeRF-style: the loaders add ".png"
        camera = json.loads(stem.with_name(stem.name + "_camera.json").read_text())
        assert camera["camera_to_world"] == frame["transform_matrix"]
        world = np.load(stem.with_name(stem.name + "_position.npy"))
        depth = np.load(out / frame["depth_file_path"])
        hits = np.argwhere(depth > 0)
        assert len(hits) > depth.size // 4
        for v, u in hits[:: max(1, len(hits) // 25)]:
            np.testing.assert_allclose(back_project(frame, t, out, u, v), world[v, u], atol=2e-3 * depth[v, u])
    return t


def test_sphere_views_write_images_depth_cameras_and_transforms(tmp_path):
    run = rayvr("capture", "--views", "sphere:3", "--size", "20x14", "--aux", "position", "--out", str(tmp_path), "-q")
    assert run.returncode == 0, run.stderr
    t = check_transforms(tmp_path, 6)  # 3 views x 2 eyes, each eye its own camera
    assert t["w"] == 20 and t["h"] == 14 and math.isclose(t["fl_x"], t["fl_y"])
    left, right = (np.asarray(f["transform_matrix"])[:3, 3] for f in t["frames"][:2])
    assert math.isclose(np.linalg.norm(right - left), 0.064, rel_tol=1e-9)  # the IPD apart


def test_view_file_intrinsics_reach_the_image_and_transforms_json(tmp_path):
    views = {"camera_angle_x": 1.0, "views": [
        {"position": [0.5, 1.4, 3.0], "target": [0, 1, 0], "fl_x": 14.0, "fl_y": 12.0, "cx": 9.0, "cy": 5.0},
        {"transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 1.2], [0, 0, 1, 3.2], [0, 0, 0, 1]], "w": 20, "h": 14},
    ]}
    (tmp_path / "views.json").write_text(json.dumps(views))
    out = tmp_path / "o"
    run = rayvr("capture", "--views", str(tmp_path / "views.json"), "--size", "20x14", "--eye", "left", "--ipd", "0",
                "--aux", "position", "--out", str(out), "-q")
    assert run.returncode == 0, run.stderr
    t = check_transforms(out, 2)
    first, second = ({k: f.get(k, t.get(k)) for k in ("fl_x", "fl_y", "cx", "cy", "camera_angle_x")} for f in t["frames"])
    assert (first["fl_x"], first["fl_y"], first["cx"], first["cy"]) == pytest.approx((14.0, 12.0, 9.0, 5.0))
    assert second["camera_angle_x"] == pytest.approx(1.0)  # the file's default
    # An independent check of the off-centre view: project its world points with the input intrinsics.
    world = np.load(out / "frame_0000_left_position.npy")
    pose = Pose.look_at([0.5, 1.4, 3.0], [0, 1, 0])
    cam = (world.reshape(-1, 3) - pose.position) @ pose.rotation  # camera coordinates
    u = 14.0 * cam[:, 0] / -cam[:, 2] + 9.0
    v = -12.0 * cam[:, 1] / -cam[:, 2] + 5.0
    hit = np.load(out / "frame_0000_left_depth.npy").ravel() > 0
    px, py = np.meshgrid(np.arange(20) + 0.5, np.arange(14) + 0.5)
    np.testing.assert_allclose(u[hit], px.ravel()[hit], atol=0.02)
    np.testing.assert_allclose(v[hit], py.ravel()[hit], atol=0.02)
    # transforms.json replays as a views file: the same cameras.
    poses, overrides = load_views(out / "transforms.json", (20, 14))
    np.testing.assert_allclose(poses[0].position, [0.5, 1.4, 3.0], atol=1e-12)
    np.testing.assert_allclose(overrides[0]["eye_tangents"]["left"], (-9 / 14, 11 / 14, -9 / 12, 5 / 12))


def test_generated_views():
    center = np.array([1.0, 2.0, 3.0])
    sphere = sphere_views(center, 2.0, 50)
    d = np.array([p.position - center for p in sphere])
    assert np.allclose(np.linalg.norm(d, axis=1), 2.0)
    assert abs(d.mean(axis=0)).max() < 0.1  # spread evenly over the sphere
    for p in sphere:  # each looks at the centre (camera -Z)
        np.testing.assert_allclose(-p.rotation[:, 2], (center - p.position) / 2.0, atol=1e-9)
    base = Pose.look_at([0, 0, 5], [0, 0, 0])
    grid = grid_views(base, 3, 2, 0.1)
    assert len(grid) == 6 and all(np.array_equal(g.rotation, base.rotation) for g in grid)
    xy = np.array([g.position[:2] for g in grid])
    np.testing.assert_allclose(xy[0], [-0.1, 0.05]) and np.testing.assert_allclose(xy[-1], [0.1, -0.05])


@pytest.mark.parametrize("views, words", [
    ("[]", ["non-empty list"]),
    ("{\"poses\": []}", ["'views' or 'frames'"]),
    ("not json", ["not a views file"]),
    ("[{\"position\": [0, 0, 1]}]", ["view 0", "needs 'transform_matrix'"]),
    ("[{\"position\": [0, 0, 1], \"target\": [0, 0, 0], \"focal\": 3}]", ["view 0", "unknown key 'focal'"]),
    ("[{\"position\": [0, 0, 1], \"target\": [0, 0, 0], \"w\": 64}]", ["64x16", "--size is 24x16"]),
    ("[{\"position\": [0, 0, 1], \"target\": [0, 0, 0], \"fov_y\": 60, \"fl_x\": 3}]", ["one of fov_y"]),
    ("[{\"position\": [0, 0, 1], \"target\": [0, 0, 0], \"fl_x\": 10, \"cx\": 30}]", ["principal point"]),
    ("[{\"position\": [0, 0, 1], \"target\": [0, 0, 0], \"cy\": 3}]", ["'cy' needs 'fl_x'"]),
    ("[{\"position\": [0, 0, 1], \"target\": [0, 0, 0], \"fov_y\": \"wide\"}]", ["'fov_y' must be a finite number"]),
    ("[{\"transform_matrix\": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]", ["not a rotation"]),
    ("[{\"transform_matrix\": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]", ["4x4"]),
])
def test_bad_views_file_names_file_view_and_key(tmp_path, views, words):
    p = tmp_path / "views.json"
    p.write_text(views)
    with pytest.raises(ValueError) as e:
        load_views(p, (24, 16))
    assert str(p) in str(e.value) and all(w in str(e.value) for w in words), str(e.value)


@pytest.mark.parametrize("spec, words", [("sphere:0", ["sphere:N"]), ("grid:3", ["grid:NxM"]),
                                         ("grid:2x2:-1", ["positive spacing"])])
def test_bad_generated_views_spec(spec, words):
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene.loader import load

    scene = load(None)
    with pytest.raises(ValueError) as e:
        views_for(spec, scene, StereoRig.for_scene(scene))
    assert all(w in str(e.value) for w in words)


def test_bad_views_is_one_line_on_the_command_line(tmp_path):
    (tmp_path / "v.json").write_text("[{\"position\": [0, 0, 1]}]")
    run = rayvr("capture", "--views", str(tmp_path / "v.json"), "--out", str(tmp_path / "o"))
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and "view 0" in run.stderr
    assert not (tmp_path / "o").exists()


def test_sphere_views_in_the_built_in_room_stand_inside_it_above_the_floor_and_outside_its_objects():
    # The room's bounds hold its camera: the sphere around the view's target once reached 0.7 m
    # under the floor and 0.1 m over the ceiling.
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene import loader

    room = loader.load(None)
    rig = StereoRig.for_scene(room, size=(32, 32))
    poses, _ = views_for("sphere:64", room, rig)
    assert len(poses) == 64
    (x0, y0, z0), (x1, y1, z1) = room.bounds
    objects = {}
    for i, m in enumerate(room.materials):
        corners = room.world_vertices()[room.indices[room.triangle_material == i].ravel()]
        objects[m.name] = corners.min(axis=0), corners.max(axis=0)
    solid = [objects[n] for n in ("glass", "box_blue", "box_white", "gold", "mirror")]
    for k, pose in enumerate(poses):
        for eye in rig.__class__(**{**rig.__dict__, "pose": pose}).eyes():
            x, y, z = eye.position
            assert x0 < x < x1 and z0 < z < z1, (k, eye.position)  # inside the walls
            assert y0 + 0.1 < y < y1, (k, eye.position)  # above the floor, under the ceiling
            assert not any(np.all(eye.position > lo) and np.all(eye.position < hi) for lo, hi in solid), k
    spread = np.array([p.position for p in poses])
    assert np.ptp(spread, axis=0).min() > 1.0  # still views from every side, not a huddle


def test_sphere_views_around_an_object_keep_the_sphere_through_the_camera():
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene import loader

    cube = loader.from_arrays(np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float),
                              np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                                        [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]))
    rig = StereoRig.for_scene(cube, size=(32, 32))
    poses, _ = views_for("sphere:8", cube, rig)
    distance = np.linalg.norm(rig.pose.position - cube.center)
    np.testing.assert_allclose([np.linalg.norm(p.position - cube.center) for p in poses], distance)


def test_transforms_names_each_material_id_so_masks_can_be_read_per_material(tmp_path):
    """With --aux material, each frame lists its material-ID image and the top maps the IDs to the
    scene's material names: the mask of a material is `ids == k`, and its pixels are the ones whose
    triangle (the triangle aux) belongs to that material in the loaded scene."""
    from rayvr.scene.loader import load

    run = rayvr("capture", "--views", "sphere:2", "--size", "24x16", "--aux", "material,triangle",
                "--out", str(tmp_path), "-q")
    assert run.returncode == 0, run.stderr
    t = json.loads((tmp_path / "transforms.json").read_text())
    scene = load(None)
    names = {int(k): v for k, v in t["materials"].items() if k != "background"}
    assert names == dict(enumerate(scene.material_names()))
    seen = set()
    for frame in t["frames"]:
        ids = np.load(tmp_path / frame["material_file_path"])
        tris = np.load(tmp_path / f"{frame['file_path']}_triangle.npy")
        hit = tris != t["materials"]["background"]
        assert hit.any() and ((ids == t["materials"]["background"]) == ~hit).all()
        np.testing.assert_array_equal(ids[hit], scene.triangle_material[tris[hit]])
        seen |= {names[k] for k in np.unique(ids[hit])}
    assert {"floor", "walls"} <= seen


def test_distance_is_the_depth_along_each_pixels_ray(tmp_path):
    """--aux distance: the other depth convention. Through transforms.json's pinhole intrinsics alone,
    a pixel's distance is its linear depth times the length of its ray (x_n, y_n, 1), and 0 where
    the depth says no surface."""
    run = rayvr("capture", "--views", "sphere:2", "--size", "24x16", "--aux", "depth,distance",
                "--out", str(tmp_path), "-q")
    assert run.returncode == 0, run.stderr
    t = json.loads((tmp_path / "transforms.json").read_text())
    for frame in t["frames"]:
        k = {key: frame.get(key, t.get(key)) for key in ("fl_x", "fl_y", "cx", "cy")}
        depth = np.load(tmp_path / frame["depth_file_path"])
        distance = np.load(tmp_path / frame["distance_file_path"])
        v, u = np.mgrid[0:depth.shape[0], 0:depth.shape[1]]
        ray = np.sqrt(((u + 0.5 - k["cx"]) / k["fl_x"]) ** 2 + ((v + 0.5 - k["cy"]) / k["fl_y"]) ** 2 + 1.0)
        hit = depth > 0
        assert hit.mean() > 0.5 and (distance[~hit] == 0).all()
        np.testing.assert_allclose(distance[hit], depth[hit] * ray[hit], rtol=1e-4)
