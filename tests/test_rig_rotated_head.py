"""The stereo eyes under a rotated head (rayvr/frame/cameras/rig.py StereoRig.eye): each eye sits
ipd / 2 along the head's own right axis, so a point straight ahead of the head lies at eye-space
x = +ipd/2 for the left eye and -ipd/2 for the right, whatever the head's yaw, pitch and roll.
Every other stereo test uses an identity pose, where the head's right axis is world +X: an eye
offset along world X passes them all. Checked on the rig's matrices and on rendered frames (raster
and ray-cast primary visibility) against the analytic disparity."""
import math

import numpy as np
import pytest

from conftest import quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import from_arrays

SIZE = (64, 48)
FOV = 40.0
IPD = 0.5   # large, so the disparity is several pixels
AHEAD = 2.0  # m from the head to the marker
HEAD = np.array([0.3, 1.6, -0.4])


def axis_rotation(axis: int, degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [k for k in range(3) if k != axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m if axis != 1 else m.T  # about Y the right-handed sign flips with the (z, x) order


def rotated_head(yaw=37.0, pitch=-21.0, roll=14.0) -> Pose:
    """Yaw about world Y, then pitch about the head's X, then roll about its Z (not Pose.look_at)."""
    r = axis_rotation(1, yaw) @ axis_rotation(0, pitch) @ axis_rotation(2, roll)
    assert np.allclose(r @ r.T, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
    return Pose(HEAD.copy(), r)


def test_eyes_sit_along_the_heads_own_right_axis():
    pose = rotated_head()
    rig = StereoRig(pose, ipd=IPD, fov_y=FOV, size=SIZE)
    ahead = HEAD + AHEAD * pose.forward
    for name, x in (("left", IPD / 2), ("right", -IPD / 2)):
        eye = rig.eye(name)
        p = eye.view_matrix() @ np.append(ahead, 1.0)
        np.testing.assert_allclose(p[:3], [x, 0.0, -AHEAD], atol=1e-12)
        assert np.linalg.norm(eye.position - HEAD) == pytest.approx(IPD / 2, abs=1e-12)
    # the eyes' baseline is perpendicular to the gaze and to the head's up: no vertical disparity
    base = rig.eye("right").position - rig.eye("left").position
    assert abs(base @ pose.forward) < 1e-12 and abs(base @ pose.rotation[:, 1]) < 1e-12


def marker_scene(pose: Pose):
    """A 0.1 m square facing the head, centred straight ahead of it."""
    right, up = pose.rotation[:, 0], pose.rotation[:, 1]
    v, f = quad(HEAD + AHEAD * pose.forward, 0.05 * right, 0.05 * up)
    return from_arrays(v.astype(np.float32), f)


def expected_column(x_eye: float) -> float:
    """Image column (pixel units, 0 at the left edge) of a point at eye-space x_eye, depth AHEAD."""
    t = math.tan(math.radians(FOV) / 2) * SIZE[0] / SIZE[1]
    return (x_eye / AHEAD + t) / (2 * t) * SIZE[0]


@pytest.mark.parametrize("primary", ["raster", "rays"])
def test_rendered_disparity_under_a_rotated_head(gl, primary):
    pose = rotated_head()
    rig = StereoRig(pose, ipd=IPD, fov_y=FOV, size=SIZE)
    with Renderer(marker_scene(pose), None, gl=gl) as r:
        r.settings = RenderSettings(primary=primary)
        frame = r.render(rig)
    for name, x in (("left", IPD / 2), ("right", -IPD / 2)):
        covered = np.asarray(getattr(frame, name).depth) > 0  # reversed-Z: the background is 0
        rows, cols = np.nonzero(covered)
        assert 4 <= len(rows) < covered.size // 4, (name, len(rows))
        assert cols.mean() + 0.5 == pytest.approx(expected_column(x), abs=0.5), name
        assert rows.mean() + 0.5 == pytest.approx(SIZE[1] / 2, abs=0.5), name  # no vertical disparity
