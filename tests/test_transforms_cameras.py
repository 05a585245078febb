"""transforms.json says each camera model's true camera, as nerfstudio reads it, or the capture is
refused. Each model's written fields are checked by projecting world points along rayvr's own numpy
rays (rayvr/frame/cameras/*) with an independent numpy implementation of nerfstudio's camera models
(nerfstudio/cameras/cameras.py: pixel (x, y) -> c = ((x - cx) / fl_x, -(y - cy) / fl_y); OPENCV is
the perspective (c, -1) after OpenCV's radial-tangential distortion, OPENCV_FISHEYE the equidistant
theta = |c| after OpenCV's fisheye polynomial, EQUIRECTANGULAR yaw pi c_x and polar angle
pi (1/2 - c_y)); they must land on the pixel centres the rays went through."""
import json
import math

import numpy as np
import pytest

from conftest import run_rayvr
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from rayvr.frame.cameras.distorted import write_samples
from rayvr.app.capture import CaptureJob
from rayvr.scene.loader import load
from rayvr.app.views import transforms, views_for

POSE = Pose.look_at([0.3, 1.4, 2.0], [-0.2, 1.0, -1.0])


def opencv(cam, k):
    x, y = cam[:, 0] / -cam[:, 2], cam[:, 1] / -cam[:, 2]
    r2 = x * x + y * y
    radial = 1 + k.get("k1", 0) * r2 + k.get("k2", 0) * r2 ** 2 + k.get("k3", 0) * r2 ** 3
    p1, p2 = k.get("p1", 0), k.get("p2", 0)
    return (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)


def opencv_fisheye(cam, k):
    rho = np.hypot(cam[:, 0], cam[:, 1])
    theta = np.arctan2(rho, -cam[:, 2])
    t2 = theta * theta
    theta_d = theta * (1 + k.get("k1", 0) * t2 + k.get("k2", 0) * t2 ** 2 + k.get("k3", 0) * t2 ** 3 +
                       k.get("k4", 0) * t2 ** 4)
    return theta_d * cam[:, 0] / rho, theta_d * cam[:, 1] / rho


def equirectangular(cam, k):
    d = cam / np.linalg.norm(cam, axis=1, keepdims=True)
    return np.arctan2(d[:, 0], -d[:, 2]) / math.pi, 0.5 - np.arccos(d[:, 1]) / math.pi


PROJECT = {"OPENCV": opencv, "OPENCV_FISHEYE": opencv_fisheye, "EQUIRECTANGULAR": equirectangular}


def project(fields, c2w, points):
    """Pixel (x, y), rows top-down, of world points in the camera the fields describe."""
    c2w = np.asarray(c2w)
    cam = (points - c2w[:3, 3]) @ c2w[:3, :3]  # camera coordinates, OpenGL axes
    cx_, cy_ = PROJECT[fields["camera_model"]](cam, fields)
    return fields["cx"] + fields["fl_x"] * cx_, fields["cy"] - fields["fl_y"] * cy_


def job_for(camera, fov=90.0, size=(24, 18), **kw):
    rig = StereoRig(POSE, ipd=0.07, fov_y=fov, size=size, camera=camera, **kw)
    poses = [POSE, Pose.look_at([-1.0, 1.2, 1.5], [0.0, 1.0, 0.0])]
    return CaptureJob(rig, poses, aux=("depth",), cameras=True)


WRITTEN = {
    "pinhole": (lambda: job_for(Pinhole(), fov=70, convergence=1.5), "OPENCV"),  # off-axis eyes: cx per eye
    "dof_without_aperture": (lambda: job_for(ThinLens(aperture=0.0)), "OPENCV"),
    "distorted_without_distortion": (lambda: job_for(Distorted(coefficients=(0.0, 0.0, 0.0))), "OPENCV"),
    "wide_spherical_200": (lambda: job_for(Wide(fov_x=200), fov=120), "EQUIRECTANGULAR"),
    "wide_spherical_full": (lambda: job_for(Wide(fov_x=360), fov=180, size=(32, 16)), "EQUIRECTANGULAR"),
    "wide_equidistant_200": (lambda: job_for(Wide(mapping="equidistant"), fov=200), "OPENCV_FISHEYE"),
    "wide_equidistant_300": (lambda: job_for(Wide(mapping="equidistant"), fov=300, size=(20, 20)), "OPENCV_FISHEYE"),
}


@pytest.mark.parametrize("name", list(WRITTEN))
def test_transforms_json_projects_world_points_where_rayvr_renders_them(name):
    make, model = WRITTEN[name]
    job = make()
    t = json.loads(json.dumps(transforms(job), allow_nan=False))  # as a reader gets it
    assert t["camera_model"] == model
    frames = iter(t["frames"])
    for i in range(len(job.poses)):
        rig = job.frame_rig(i)
        for eye_name in job.eye_names:
            frame = next(frames)
            # nerfstudio's dataparser takes a top-level intrinsic for every frame (fx_fixed = "fl_x" in meta)
            fields = {**frame, **{k: v for k, v in t.items() if k != "frames"}}
            eye = rig.eye(eye_name)
            rays = eye.rays()  # rayvr's numpy reference of the model
            h, w = rays.valid.shape
            ys, xs = np.nonzero(rays.valid)
            assert len(xs) > 0.7 * w * h
            for distance in (0.3, 4.0):
                points = rays.origins[ys, xs] + distance * rays.directions[ys, xs]
                u, v = project(fields, frame["transform_matrix"], points)
                np.testing.assert_allclose(u, xs + 0.5, atol=1e-6)
                np.testing.assert_allclose(v, ys + 0.5, atol=1e-6)


def test_a_fisheye_past_180_degrees_keeps_nerfstudio_to_the_pixels_with_rays():
    """nerfstudio's fisheye sampler picks pixel (floor(x), floor(y)) for points within
    fisheye_crop_radius of (w // 2, h // 2): every pixel it can pick must hold a ray."""
    job = WRITTEN["wide_equidistant_300"][0]()
    t = transforms(job)
    radius = t["fisheye_crop_radius"]
    valid = job.frame_rig(0).eye("left").rays().valid
    h, w = valid.shape
    assert not valid.all()  # the corners lie past 180 degrees
    x, y = np.meshgrid(np.arange(w), np.arange(h))
    nearest_x = np.clip(w // 2, x, x + 1) - w // 2  # the pixel square's point nearest the centre
    nearest_y = np.clip(h // 2, y, y + 1) - h // 2
    pickable = np.hypot(nearest_x, nearest_y) <= radius
    assert valid[pickable].all() and pickable[valid].mean() > 0.85
    assert "fisheye_crop_radius" not in transforms(WRITTEN["wide_equidistant_200"][0]())  # every pixel has a ray


def test_a_full_panorama_has_nerfstudios_equirectangular_intrinsics():
    t = transforms(WRITTEN["wide_spherical_full"][0]())
    assert (t["fl_x"], t["fl_y"], t["cx"], t["cy"]) == pytest.approx((16.0, 16.0, 16.0, 8.0))  # fx = fy = h = w / 2
    assert "camera_angle_x" not in t  # a pinhole's angle would misdescribe it to loaders of pinholes


def test_camera_files_carry_the_same_camera(tmp_path):
    run = run_rayvr("capture", "--size", "24x12", "--views", "sphere:1", "--camera-model", "wide", "--fov", "120",
                    "--camera-param", "fov_x=200", "--eye", "left", "--out", tmp_path, "-q")
    assert run.returncode == 0, run.stderr
    t = json.loads((tmp_path / "transforms.json").read_text())
    camera = json.loads((tmp_path / "frame_left_camera.json").read_text())
    assert t["camera_model"] == camera["camera_model"] == "EQUIRECTANGULAR"
    assert t["fl_x"] == pytest.approx(math.pi * 24 / math.radians(200)) and camera["fl_x"] == t["fl_x"]
    assert "distance along each pixel's ray" in t["convention"]  # the wide model's depth


@pytest.mark.parametrize("camera, words", [
    (lambda tmp: Distorted(), ["distorted camera", "inverse of OpenCV's radial model"]),
    (lambda tmp: Distorted(samples=str(tmp / "lens.txt")), ["distorted camera", "measured sample file"]),
    (lambda tmp: ThinLens(aperture=0.05), ["dof camera", "lens of radius 0.05"]),
    (lambda tmp: Foveated(), ["foveated camera", "between samples"]),
])
def test_cameras_transforms_json_cannot_describe_are_refused_before_rendering(tmp_path, camera, words):
    write_samples(tmp_path / "lens.txt", np.tile([0.0, 0.0, -1.0], (1, 18, 24, 1)))
    scene = load(None)
    rig = StereoRig.for_scene(scene, size=(24, 18), camera=camera(tmp_path))
    with pytest.raises(ValueError) as e:
        views_for("sphere:2", scene, rig)
    message = str(e.value)
    assert message.startswith("--views sphere:2: view 0: transforms.json (nerfstudio's camera models) cannot "
                              "describe the ") and all(w in message for w in words), message


def test_refused_camera_is_one_line_and_writes_nothing(tmp_path):
    run = run_rayvr("capture", "--size", "16x12", "--views", "sphere:2", "--camera-model", "distorted",
                    "--out", tmp_path / "o")
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "cannot describe the distorted camera" in lines[0], run.stderr
    assert not (tmp_path / "o").exists()


def test_a_transforms_json_of_another_camera_model_is_not_replayed_as_pinholes(tmp_path):
    (tmp_path / "t.json").write_text(json.dumps({"camera_model": "OPENCV_FISHEYE", "fl_x": 10.0, "frames": [
        {"transform_matrix": np.eye(4).tolist()}]}))
    from rayvr.app.views import load_views

    with pytest.raises(ValueError, match=r"t\.json: camera_model 'OPENCV_FISHEYE': a views file's intrinsics are "
                                         r"a pinhole's"):
        load_views(tmp_path / "t.json", (24, 18))
