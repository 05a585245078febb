"""Values that are finite in float64 but overflow or flush to zero in the GPU's float32 (rayvr/gl/limits.py
and the camera checks that use it): refused in one line before any work, or rendered right at the
edge of their range; and every JSON a capture writes is valid JSON (no NaN or Infinity)."""
import json
import math

import numpy as np
import pytest

from conftest import run_rayvr
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.pinhole import MIN_PIXEL_TANGENT
from rayvr.gl.limits import (FLOAT32_MAX, FLOAT32_NORMAL_MIN, MAX_CAMERA_COORDINATE, MAX_DISTANCE, MIN_DISTANCE,
                          check_range, to_float32)


# ---------------------------------------------------------------- the shared helper

def test_check_range_takes_the_interval_and_names_the_value_and_its_range():
    assert check_range("near", 1e-18, 1e-18, 1e30) == 1e-18 and check_range("near", 1e30, 1e-18, 1e30) == 1e30
    assert check_range("n", 3, 0, 5) == 3.0 and isinstance(check_range("n", 3, 0, 5), float)
    for value in (1e-19, 2e30, float("nan"), float("inf"), -float("inf")):
        with pytest.raises(ValueError, match=r"^near must be in \[1e-18, 1e\+30\], got "):
            check_range("near", value, 1e-18, 1e30)
    with pytest.raises(ValueError, match=r"must be in \(0, 1\), got 0"):
        check_range("x", 0.0, 0.0, 1.0, lo_open=True, hi_open=True)
    with pytest.raises(ValueError, match=r"must be in \(0, 1\), got 1"):
        check_range("x", 1.0, 0.0, 1.0, lo_open=True, hi_open=True)
    for value in (True, "1", None, (1,)):
        with pytest.raises(ValueError, match="must be a number"):
            check_range("x", value, 0.0, 1.0)


def test_the_ranges_keep_the_gpu_maths_inside_float32():
    # reversed-Z depth near / distance stays a normal number for the shortest near and the farthest camera
    assert MIN_DISTANCE / MAX_CAMERA_COORDINATE > 10 * FLOAT32_NORMAL_MIN
    # squared camera distances (ray lengths, ray-box and ray-sphere maths) and the depth maths stay finite
    assert (2 * MAX_CAMERA_COORDINATE) ** 2 < FLOAT32_MAX / 50 and MAX_DISTANCE * 1e6 < FLOAT32_MAX


def test_to_float32_refuses_what_overflows_float32_and_keeps_the_rest():
    a = to_float32("a", [[3.4e38, -1.0], [1e-45, 0.0]])
    assert a.dtype == np.float32 and a[0, 0] == np.float32(3.4e38) and a[0, 1] == -1.0
    assert float(np.float32(FLOAT32_MAX)) == FLOAT32_MAX
    for bad in (1e39, -1e300, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=r"^camera position: .* does not fit the GPU's float32"):
            to_float32("camera position", [0.0, bad])


# ---------------------------------------------------------------- refused on the command line

@pytest.mark.parametrize("args, words", [
    (["--camera-model", "dof", "--camera-param", "aperture=1e300"], ["aperture", "[0, 1e+18]", "1e+300"]),
    (["--camera-model", "dof", "--camera-param", "aperture=1e12"],  # was all background
     ["dof camera: aperture 1e+12 is wider than 1.07e+05", "0.1 of a pixel at focus 2"]),
    (["--camera-model", "dof", "--camera-param", "focus=1e-40"], ["focus distance", "[1e-18, 1e+12]"]),
    (["--camera-model", "dof", "--camera-param", "focus=1e25"], ["focus distance", "[1e-18, 1e+12]"]),  # was blank
    (["--camera-model", "distorted", "--camera-param", "coefficients=1e39"],
     ["distorted camera", "view tangent 2.", "e+39", "rays end at tangent 1e+05"]),
    (["--camera-model", "distorted", "--camera-param", "coefficients=1e308,-1e308"], ["view tangent inf"]),
    (["--camera-model", "distorted", "--camera-param", "center=1e300,0"], ["center x", "[-100000, 100000]"]),
    (["--near", "1e-40"], ["near must be in [1e-18, 1e+30], got 1e-40"]),
    (["--fov", "1e-7"], ["fov_y 1e-07 on a 16x12 image", "fov_y 0.000688 degrees at least", "tangent of 1e-06"]),
    (["--fov", "1e-40"], ["fov_y 1e-40", "at least"]),
    (["--primary", "rays", "--fov", "1e-7"], ["fov_y 1e-07"]),
    (["--camera-model", "wide", "--fov", "1e-7"], ["wide camera", "radians"]),
    (["--views", "grid:5x1:1e308"], ["--views grid:NxM:SPACING", "at most 2e+17", "'1e308'"]),
    (["--views", "grid:5x1:1e300"], ["at most 2e+17"]),
])
def test_values_that_overflow_float32_are_one_clear_line(tmp_path, args, words):
    out = tmp_path / "o"
    run = run_rayvr("capture", "--size", "16x12", "--out", out, *args)
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1 and lines[0].startswith("rayvr capture: error: "), run.stderr
    assert all(w in lines[0] for w in words), lines[0]
    assert not out.exists()


def test_views_file_focal_length_beyond_float32_precision_is_one_line(tmp_path):
    views = tmp_path / "views.json"
    views.write_text(json.dumps([{"position": [0, 1.5, 3], "target": [0, 1, 0], "fl_x": 1e12}]))
    run = run_rayvr("capture", "--size", "16x12", "--views", views, "--out", tmp_path / "o")
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert f"{views}: view 0: 'fl_x' (pixels) must be in [" in lines[0] and "1e+06]" in lines[0]
    assert not (tmp_path / "o").exists()


def test_camera_positions_beyond_float32_are_one_line_before_any_frame(tmp_path):
    """A path whose second pose lies 1e300 away used to render its first frame and then fail on
    the GPU upload; an eye at 1e300 overflowed look_at's norm (NaN rotation, numpy warnings)."""
    path = tmp_path / "path.json"
    path.write_text(json.dumps({"poses": [{"position": [0, 1.5, 3], "target": [0, 1, 0]},
                                          {"position": [1e300, 1.5, 3], "target": [0, 1, 0]}]}))
    for args, words in ((["--path", path], f"{path}: pose 1: the camera at [1e+300, 1.5, 3.0] lies 1e+300 from"),
                        (["--camera", "1e300,0,0,0,0,0"], "camera pose 0: the camera at [1e+300, 0.0, 0.0]")):
        out = tmp_path / "o"
        run = run_rayvr("capture", "--size", "16x12", "--out", out, *args)
        lines = run.stderr.splitlines()
        assert run.returncode == 2 and len(lines) == 1 and words in lines[0], run.stderr
        assert "at most 1e+18 (float32 on the GPU)" in lines[0] and not out.exists()


def test_view_positions_are_checked_against_the_scene_before_rendering():
    from rayvr.scene.loader import load
    from rayvr.app.views import views_for

    scene = load(None)
    rig = StereoRig.for_scene(scene, size=(16, 12))
    rig.pose = Pose(np.array([3e18, 1.0, 0.0]), np.eye(3))
    with pytest.raises(ValueError, match=r"--views grid:2x1:1: view 0: the camera at .* lies 3e\+18 from the scene's "
                                         r"centre along an axis; at most 1e\+18"):
        views_for("grid:2x1:1", scene, rig)


# ---------------------------------------------------------------- the rig and models refuse directly

@pytest.mark.parametrize("kw, words", [
    (dict(near=1e-40), "near must be in"), (dict(near=1e31), "near must be in"),
    (dict(far=1e31), "far must be in"), (dict(ipd=1e19), r"ipd must be in \[0, 1e\+18\]"),
    (dict(convergence=1e300), "convergence distance must be in"),
    (dict(eye_tangents={"left": (-1e-8, 1e-8, -1e-8, 1e-8), "right": (-1, 1, -1, 1)}),
     r"eye_tangents\['left'\] .* make pixels of tangent"),
])
def test_rig_values_outside_float32_ranges_are_refused(kw, words):
    with pytest.raises(ValueError, match=words):
        StereoRig(size=(16, 12), **kw)


def test_infinite_far_is_the_infinite_far_plane():
    assert StereoRig(far=float("inf")).far is None


def test_the_fold_check_cannot_overflow_into_a_pass():
    """Coefficients whose float64 slope is inf - inf = NaN (which compares as no fold) and a
    polynomial whose slope dips below 0 between any sampled radii are both refused."""
    with pytest.raises(ValueError, match="view tangent inf"):
        StereoRig(size=(16, 12), camera=Distorted(coefficients=(1e308, -1e308, 0.0)))
    # slope 1 + 3 k1 x + 5 k2 x^2 (x = r^2) has its minimum -1e-12 at x = x0 = r0^2, so it folds only
    # within ~1e-6 of r0, put half-way between two of the 4096 radii the check used to sample over
    # the panel's reach (5/3: the corner of a 90-degree 4:3 frustum).
    r0 = 2000.5 * (5 / 3) / 4095
    k2 = (1 + 1e-12) / (5 * r0 ** 4)
    fold = Distorted(coefficients=(-10 * k2 * r0 * r0 / 3, k2, 0.0))
    with pytest.raises(ValueError, match=rf"folds over at radius {r0:.4g} "):
        StereoRig(size=(16, 12), fov_y=90, camera=fold)
    StereoRig(size=(16, 12), fov_y=90, camera=Distorted(coefficients=(-10 * 0.2 / 3 * 0.999, 0.2, 0.0)))


# ---------------------------------------------------------------- rendered right at the edges

def numpy_triangle_ids(scene, eye):
    """Closest-hit triangle per pixel in float64 (Moller-Trumbore over every triangle)."""
    v = scene.world_vertices()
    tri = scene.indices.reshape(-1, 3)
    v0, e1, e2 = v[tri[:, 0]], v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]]
    d = eye.rays().directions.reshape(-1, 3)
    s = eye.position - v0
    q = np.cross(s, e1)
    ids = np.full(len(d), 0xFFFFFFFF, np.int64)
    for k in range(0, len(d), 512):
        dd = d[k:k + 512]
        p = np.cross(dd[:, None, :], e2[None])
        det = np.einsum("rtk,tk->rt", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("tk,rtk->rt", s, p) / det
            w = dd @ q.T / det
            t = np.einsum("tk,tk->t", e2, q)[None] / det
        t = np.where((u >= 0) & (w >= 0) & (u + w <= 1) & (t > eye.near), t, np.inf)
        j = t.argmin(axis=1)
        ids[k:k + 512] = np.where(np.isfinite(t[np.arange(len(j)), j]), j, 0xFFFFFFFF)
    return ids.reshape(eye.size[1], eye.size[0])


def test_the_narrowest_fov_renders_right_in_raster_and_rays(gl):
    """At the smallest pixel step the pinhole takes, both primary paths see the triangles a float64
    trace sees, at a mesh vertex where six triangles meet (measured: raster 100 %, rays 99.8 % at a
    third of the step; at 1e-6 degrees rays found 17 %)."""
    from rayvr import Renderer
    from rayvr.renderer import RenderSettings
    from rayvr.scene.loader import load

    scene, size = load(None), (48, 36)
    corner = scene.world_vertices()[scene.indices.reshape(-1, 3)[len(scene.indices) // 9, 0]]
    pose = Pose.look_at(corner + [0.7, 0.4, 1.5], corner)
    fov = math.degrees(2 * math.atan(MIN_PIXEL_TANGENT * size[1] / 2)) * (1 + 1e-9)
    rig = StereoRig(pose, fov_y=fov, size=size, ipd=0.0, near=1e-3)
    with pytest.raises(ValueError, match="at least here"):
        StereoRig(pose, fov_y=fov * 0.99, size=size, ipd=0.0, near=1e-3)
    want = numpy_triangle_ids(scene, rig.eye("left"))
    assert len(np.unique(want)) >= 3  # the vertex is in view: several triangles, no background
    for primary in ("raster", "rays"):
        with Renderer(scene, gl=gl, settings=RenderSettings(primary=primary)) as r:
            got = r.render(rig, eyes="left", aux=("triangle",)).eyes["left"].aux["triangle"]
        assert (got == want).mean() >= 0.99, (primary, (got == want).mean())


def test_the_shortest_near_plane_renders_the_same_depths(gl):
    """near 1e-18: reversed-Z depth near / distance stays a normal float32; the frame equals near 0.05's."""
    from rayvr import Renderer
    from rayvr.scene.loader import load

    scene = load(None)
    pose = Pose.look_at([0.3, 1.5, 2.5], [0, 1.2, -1])
    with Renderer(scene, gl=gl) as r:
        depth = [r.render(StereoRig(pose, size=(32, 24), near=n), eyes="left", aux=("depth",)).eyes["left"].aux["depth"]
                 for n in (0.05, 1e-18)]
    assert (depth[0] > 0).all()
    np.testing.assert_allclose(depth[1], depth[0], rtol=1e-5)


# ---------------------------------------------------------------- every JSON valid

def strict_json(path):
    def refuse(name):
        raise AssertionError(f"{path}: {name} is not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def test_every_json_a_multi_view_capture_writes_is_valid_json(tmp_path):
    """--far inf used to reach the camera files as `Infinity`; camera files and transforms.json
    now say an infinite far plane as null."""
    run = run_rayvr("capture", "--size", "16x12", "--views", "sphere:2", "--far", "inf", "--out", tmp_path, "-q")
    assert run.returncode == 0, run.stderr
    files = sorted(tmp_path.glob("*.json"))
    assert len(files) >= 6  # 4 camera files, transforms.json, the job and timings files
    for p in files:
        strict_json(p)
    camera = strict_json(tmp_path / "frame_0000_left_camera.json")
    assert camera["far"] is None and camera["near"] > 0


@pytest.mark.parametrize("kw, words", [(dict(dof_diameter=1e300), r"dof_diameter must be in \[0, 1e\+18\]"),
                                       (dict(dof_focus=1e-300), r"dof_focus must be in \[1e-18, 1e\+12\]"),
                                       (dict(dof_focus=1e25), r"dof_focus must be in \[1e-18, 1e\+12\]")])
def test_render_settings_dof_values_stay_in_float32_ranges(kw, words):
    from rayvr.renderer import RenderSettings

    with pytest.raises(ValueError, match=words):
        RenderSettings(**kw)
