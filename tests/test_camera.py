import json
import math

import numpy as np
import pytest

from rayvr.frame.cameras.rig import Pose, StereoRig, load_path, orbit, projection, save_path


def test_reversed_z_infinite_depth_is_near_over_distance():
    p = projection(-1, 1, -1, 1, near=0.1)
    for d in (0.1, 1.0, 1e3, 1e7):
        clip = p @ np.array([0, 0, -d, 1.0])
        assert clip[2] / clip[3] == pytest.approx(0.1 / d, rel=1e-12)


def test_finite_far_maps_near_to_one_far_to_zero():
    p = projection(-1, 1, -1, 1, near=0.5, far=100.0)
    z = lambda d: (p @ [0, 0, -d, 1.0])[2] / (p @ [0, 0, -d, 1.0])[3]
    assert z(0.5) == pytest.approx(1.0) and z(100.0) == pytest.approx(0.0, abs=1e-12)
    m1 = projection(-1, 1, -1, 1, near=0.5, far=100.0, zero_to_one=False)
    z1 = lambda d: (m1 @ [0, 0, -d, 1.0])[2] / (m1 @ [0, 0, -d, 1.0])[3]
    assert z1(0.5) == pytest.approx(1.0) and z1(100.0) == pytest.approx(-1.0)


def test_project_and_rays_agree_per_pixel():
    rig = StereoRig(Pose.look_at([1, 2, 3], [0, 0, 0]), ipd=0.1, fov_y=70, size=(64, 48), convergence=2.0)
    for eye in rig.eyes():
        d = eye.ray_directions()
        for (y, x) in [(0, 0), (47, 63), (20, 31)]:
            px, py, _ = eye.project(eye.position + 3.7 * d[y, x])[0]
            assert px == pytest.approx(x + 0.5, abs=1e-9) and py == pytest.approx(y + 0.5, abs=1e-9)


def test_parallel_eyes_disparity_matches_formula():
    w, h, fov, ipd, D = 200, 100, 60.0, 0.064, 2.5
    rig = StereoRig(Pose(), ipd=ipd, fov_y=fov, size=(w, h))
    point = np.array([0.0, 0.0, -D])
    xl = rig.eye("left").project(point)[0, 0]
    xr = rig.eye("right").project(point)[0, 0]
    focal_px = (h / 2) / math.tan(math.radians(fov) / 2)
    assert xl - xr == pytest.approx(focal_px * ipd / D, rel=1e-9)


def test_convergence_gives_zero_parallax_at_that_distance():
    rig = StereoRig(Pose(), ipd=0.07, fov_y=60, size=(128, 128), convergence=3.0)
    at = np.array([0.3, -0.2, -3.0])
    l, r = rig.eye("left").project(at)[0], rig.eye("right").project(at)[0]
    assert l[0] == pytest.approx(r[0], abs=1e-9) and l[1] == pytest.approx(r[1], abs=1e-9)
    near = rig.eye("left").project([0, 0, -1.0])[0, 0] - rig.eye("right").project([0, 0, -1.0])[0, 0]
    assert near > 0  # nearer than convergence: crossed disparity


def test_hmd_tangents_are_used_verbatim():
    tangents = {"left": (-1.3, 1.0, -1.1, 1.2), "right": (-1.0, 1.3, -1.1, 1.2)}
    rig = StereoRig(Pose(), eye_tangents=tangents, size=(100, 100))
    e = rig.eye("left")
    assert e.tangents == tangents["left"]
    x = e.project(e.position + [-1.3, 0.0, -1.0])[0, 0]  # on the left frustum edge
    assert x == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("kw", [dict(ipd=-1), dict(ipd=float("nan")), dict(fov_y=180), dict(fov_y=0),
                                dict(convergence=0.0), dict(size=(0, 10)), dict(near=0.0), dict(near=-1.0),
                                dict(near=float("inf")), dict(near=float("nan")), dict(near=1.0, far=1.0),
                                dict(near=1.0, far=0.5), dict(far=float("nan"))])
def test_bad_rig_values_rejected(kw):
    with pytest.raises(ValueError):
        StereoRig(**kw)


def test_ipd_zero_gives_identical_eyes():
    rig = StereoRig(Pose.look_at([0, 1, 2], [0, 0, 0]), ipd=0.0)
    assert np.allclose(rig.eye("left").view_matrix(), rig.eye("right").view_matrix())


def test_camera_path_roundtrip(tmp_path):
    poses = orbit([0, 0, 0], 2.0, 1.0, 5)
    save_path(tmp_path / "p.json", poses, source="test")
    back = load_path(tmp_path / "p.json")
    assert len(back) == 5
    for a, b in zip(poses, back):
        assert np.allclose(a.position, b.position) and np.allclose(a.rotation, b.rotation)
    (tmp_path / "bad.json").write_text('{"poses": [{"position": [0, 0, NaN], "target": [0, 0, -1]}]}')
    with pytest.raises(ValueError, match="NaN"):
        load_path(tmp_path / "bad.json")
    (tmp_path / "empty.json").write_text('{"poses": []}')
    with pytest.raises(ValueError, match="no poses"):
        load_path(tmp_path / "empty.json")


def test_camera_path_rotations_must_be_rotations(tmp_path):
    p = tmp_path / "p.json"
    pose = {"position": [0, 1, 2], "rotation": np.eye(3).tolist()}

    def write(rotation):
        p.write_text(json.dumps({"poses": [pose, {"position": [0, 1, 2], "rotation": rotation}]}))
        return p

    with pytest.raises(ValueError, match=r"p\.json: pose 1: rotation is not a rotation matrix.*det 0"):
        load_path(write(np.zeros((3, 3)).tolist()))
    skewed = np.eye(3)
    skewed[0, 1] = 0.1
    with pytest.raises(ValueError, match="pose 1: rotation is not a rotation matrix"):
        load_path(write(skewed.tolist()))
    with pytest.raises(ValueError, match="det -1"):
        load_path(write(np.diag([1.0, 1.0, -1.0]).tolist()))
    # Six decimals, as a hand-written file has them, are a rotation.
    rounded = np.round(Pose.look_at([1, 2, 3], [0, 0, 0]).rotation, 6)
    assert np.array_equal(load_path(write(rounded.tolist()))[1].rotation, rounded)
    with pytest.raises(ValueError, match="pose 1: not a pose"):
        load_path(write([1, 2, 3]))
    p.write_text(json.dumps({"poses": [{"position": [0, 0], "rotation": np.eye(3).tolist()}]}))
    with pytest.raises(ValueError, match="pose 0: position must be 3 numbers"):
        load_path(p)
