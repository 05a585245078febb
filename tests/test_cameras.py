"""Camera models (rayvr/frame/cameras/): the pinhole's numpy rays and footprints, its GLSL twin, the
registry and the pinhole's field-of-view limit."""
import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from rayvr.gl import shaders
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import CAMERA_MODELS, Pinhole, get_camera_model
from rayvr.frame.cameras.pinhole import MAX_TANGENT
from rayvr.frame.passes.compute import set_eye_uniforms

HMD_TANGENTS = {"left": (-1.3, 1.0, -1.1, 1.2), "right": (-1.0, 1.3, -1.1, 1.2)}


def converged_rig(size=(13, 9)):
    return StereoRig(Pose.look_at([1.0, 2.0, 3.0], [0.2, 0.1, -0.3]), ipd=0.3, fov_y=70, size=size,
                     convergence=2.0)


def hmd_rig(size=(11, 10)):
    return StereoRig(Pose.look_at([-0.5, 1.6, 0.4], [0.3, 1.2, -2.0]), ipd=0.064, eye_tangents=HMD_TANGENTS,
                     size=size)


def expected_directions(rotation, tangents, size):
    """Unit directions through pixel centres, pixel by pixel from the frustum tangents."""
    l, r, b, t = tangents
    w, h = size
    out = np.zeros((h, w, 3))
    for row in range(h):
        for col in range(w):
            u, v = (col + 0.5) / w, (row + 0.5) / h  # v from the top row down
            d = rotation @ np.array([l * (1 - u) + r * u, t * (1 - v) + b * v, -1.0])
            out[row, col] = d / math.sqrt(d @ d)
    return out


# ---------------------------------------------------------------- (1) pinhole rays

def test_pinhole_rays_are_pixel_centre_rays_of_off_axis_eyes():
    rig = converged_rig()
    t = math.tan(math.radians(70) / 2)
    a = 13 / 9
    for eye, sign in zip(rig.eyes(), (-1, 1)):
        shift = -sign * 0.15 / 2.0  # sheared for zero parallax at 2 m: -offset / convergence
        assert eye.tangents == pytest.approx((-t * a + shift, t * a + shift, -t, t), abs=1e-15)
        rays = eye.camera.rays(eye)
        assert rays.directions.shape == rays.ddx.shape == rays.ddy.shape == rays.origins.shape == (9, 13, 3)
        np.testing.assert_allclose(rays.directions, expected_directions(eye.rotation, eye.tangents, eye.size),
                                   atol=1e-14)
        np.testing.assert_array_equal(eye.ray_directions(), rays.directions)  # EyeView delegates
        assert np.array_equal(rays.origins, np.broadcast_to(eye.position, (9, 13, 3)))
        assert rays.valid.shape == (9, 13) and rays.valid.all()


def test_pinhole_rays_use_hmd_tangents_verbatim():
    rig = hmd_rig()
    for eye in rig.eyes():
        assert eye.tangents == HMD_TANGENTS[eye.name]
        np.testing.assert_allclose(eye.ray_directions(), expected_directions(eye.rotation, eye.tangents, eye.size),
                                   atol=1e-14)


def test_rig_default_camera_is_the_rasterizable_pinhole():
    rig = StereoRig()
    assert isinstance(rig.camera, Pinhole) and rig.camera.rasterizable
    assert all(e.camera is rig.camera for e in rig.eyes())
    assert StereoRig(camera="pinhole").camera == Pinhole()
    with pytest.raises(ValueError, match="channel"):
        rig.camera.rays(rig.eye("left"), channel=1)


# ---------------------------------------------------------------- (2) footprints

def test_pinhole_footprints_are_the_derivatives_of_the_directions():
    rig = converged_rig(size=(201, 151))
    for eye in rig.eyes():
        rays = eye.camera.rays(eye)
        d = rays.directions
        fd_x = (d[:, 2:] - d[:, :-2]) / 2  # central differences: error O(pixel^2)
        fd_y = (d[2:] - d[:-2]) / 2        # rows top-down: ddy points one row down
        scale = np.abs(rays.ddx).max()
        assert np.abs(fd_x - rays.ddx[:, 1:-1]).max() < 1e-3 * scale
        assert np.abs(fd_y - rays.ddy[1:-1]).max() < 1e-3 * scale
        # Derivatives of unit vectors are orthogonal to them.
        assert np.abs(np.sum(rays.ddx * d, axis=-1)).max() < 1e-15
        assert np.abs(np.sum(rays.ddy * d, axis=-1)).max() < 1e-15


def test_centre_ray_of_a_symmetric_eye_follows_the_forward_axis():
    pose = Pose.look_at([0.4, 1.5, 2.0], [-0.3, 0.8, -1.0])
    rig = StereoRig(pose, ipd=0.064, fov_y=60, size=(31, 21))  # odd size: a pixel centre on the axis
    for eye in rig.eyes():
        rays = eye.camera.rays(eye)
        np.testing.assert_allclose(rays.directions[10, 15], pose.forward, atol=1e-15)
        dx, dy = rays.ddx[10, 15], rays.ddy[10, 15]
        assert abs(dx @ dy) < 1e-15
        # One pixel on the axis subtends tan(fov/2) / (h/2) along right and (down) -up.
        step = math.tan(math.radians(30)) / 10.5
        np.testing.assert_allclose(dx, step * pose.rotation[:, 0], atol=1e-15)
        np.testing.assert_allclose(dy, -step * pose.rotation[:, 1], atol=1e-15)


# ---------------------------------------------------------------- (3) GLSL == numpy

def glsl_rays(gl, rig, origin, channel=0, subsample=None):
    """Run glsl/cameras/camera_rays.comp for both eyes; arrays (eye, row top-down, col, 4, 3) and
    (eye, row, col, 2): valid, footprint. `subsample` (i, n): sub-ray i of the n-point set."""
    model = rig.camera
    w, h = rig.size
    n = 1 if subsample is None else subsample[1]
    prog = shaders.compute(gl.ctx, "cameras/camera_rays.comp", {**model.defines(), "CAMERA_SUBSAMPLES": n})
    fc = SimpleNamespace(eyes=rig.eyes(), scene=SimpleNamespace(origin=origin), gl=gl,
                         round=SimpleNamespace(channel=channel))
    set_eye_uniforms(prog, fc)
    prog["image_size"].value = (w, h)
    prog["subsample"].value = -1 if subsample is None else subsample[0]
    buf = gl.ctx.buffer(reserve=2 * h * w * 4 * 16)
    try:
        buf.bind_to_storage_buffer(0)
        prog.run((w + 7) // 8, (h + 7) // 8, 2)
        out = np.frombuffer(buf.read(), np.float32).reshape(2, h, w, 4, 4)
    finally:
        buf.release()
        prog.release()
    out = out[:, ::-1]  # GL rows are bottom-up
    return out[..., :3].astype(np.float64), np.stack([out[:, :, :, 0, 3], out[:, :, :, 1, 3]], axis=-1)


@pytest.mark.parametrize("make_rig", [converged_rig, hmd_rig], ids=["convergence", "hmd_tangents"])
def test_glsl_camera_ray_matches_numpy(gl, make_rig):
    rig = make_rig()
    origin = np.array([0.5, -1.0, 2.0])  # the GLSL side is scene-local
    out, flags = glsl_rays(gl, rig, origin)
    for i, eye in enumerate(rig.eyes()):
        rays = eye.camera.rays(eye)
        origins, dirs, dir_x, dir_y = (out[i, :, :, k] for k in range(4))
        np.testing.assert_array_equal(flags[i, ..., 0] == 1.0, rays.valid)
        np.testing.assert_allclose(origins, rays.origins - origin, atol=1e-6)
        np.testing.assert_allclose(dirs, rays.directions, atol=1e-6)
        # The neighbours are the next column's and the row above's (GL +y) rays ...
        np.testing.assert_allclose(dir_x[:, :-1], rays.directions[:, 1:], atol=1e-6)
        np.testing.assert_allclose(dir_y[1:], rays.directions[:-1], atol=1e-6)
        # ... so, to first order, the direction plus its footprint (GL up = minus ddy).
        bound = 2 * max(np.abs(rays.ddx).max(), np.abs(rays.ddy).max()) ** 2
        assert np.abs(dir_x - (rays.directions + rays.ddx)).max() < bound
        assert np.abs(dir_y - (rays.directions - rays.ddy)).max() < bound


def test_glsl_unknown_camera_model_fails_to_build(gl, tmp_path):
    """A model's file that is not there is named with the include that asked for it; a model id
    without its file (defines not taken from the model) is refused where camera.glsl reads it."""
    missing = tmp_path / "nope.glsl"
    with pytest.raises(shaders.ShaderError, match=r"^glsl/common/camera.glsl:\d+: #include CAMERA_MODEL_FILE "
                                                  rf"\(CAMERA_MODEL_FILE = {missing}\): shader file not found: {missing}$"):
        shaders.compute(gl.ctx, "cameras/camera_rays.comp", {**Pinhole.defines(), "CAMERA_MODEL_FILE": str(missing)})
    with pytest.raises(shaders.ShaderError, match="glsl/common/camera.glsl:\\d+ ?: .*CAMERA_MODEL without CAMERA_MODEL_FILE"):
        shaders.compute(gl.ctx, "cameras/camera_rays.comp", {"CAMERA_MODEL": "CAMERA_WIDE"})


# ---------------------------------------------------------------- (4) registry

def test_registry_lists_models_with_their_glsl():
    """Each model's defines() name its id (declared in the generated header) and its GLSL file,
    which the program built from them includes; without defines, the pinhole's."""
    header = dict(line.split()[1:3] for line in shaders.GENERATED["layout.glsl"]().splitlines()
                  if line.startswith("#define ") and len(line.split()) == 3)
    for name, cls in CAMERA_MODELS.items():
        model = get_camera_model(name)
        assert model.name == name and isinstance(model, cls)
        defines = model.defines()
        assert defines["CAMERA_MODEL"] == f"CAMERA_{name.upper()}" and defines["CAMERA_MODEL_FILE"] == model.glsl
        assert int(header[defines["CAMERA_MODEL"]]) == list(CAMERA_MODELS).index(name) + 1
        assert shaders.load_source("cameras/camera_rays.comp", defines).files[-1] == model.glsl
    assert shaders.load_source("cameras/camera_rays.comp").files[-1] == Pinhole.glsl


@pytest.mark.parametrize("make", [lambda: get_camera_model("fisheye"), lambda: StereoRig(camera="fisheye")])
def test_unknown_camera_model_is_one_clear_error(make):
    with pytest.raises(ValueError, match=r"unknown camera model 'fisheye'; allowed: pinhole, distorted, wide, foveated, dof"):
        make()


def test_rig_camera_must_be_a_model_or_a_name():
    with pytest.raises(ValueError, match="camera model or its name"):
        StereoRig(camera=42)


def test_eyes_of_one_frame_share_a_model():
    @dataclass(frozen=True)
    class Other(Pinhole):
        name = "other"

    rig = StereoRig()
    left, right = rig.eyes()
    right.camera = Other()
    with pytest.raises(ValueError, match="share a camera model"):
        rig.camera.uniforms([left, right], (0, 0, 0))


# ---------------------------------------------------------------- (5) field of view

@pytest.mark.parametrize("fov", [180, 200.0, 359])
def test_pinhole_refuses_fov_of_180_and_more(fov):
    with pytest.raises(ValueError, match=r"fov_y must be in \(0, 180\) degrees for a planar projection"):
        StereoRig(fov_y=fov)


@pytest.mark.parametrize("fov", [0, -10, float("nan"), float("inf")])
def test_rig_refuses_fov_that_no_model_can_use(fov):
    with pytest.raises(ValueError, match="fov_y"):
        StereoRig(fov_y=fov)


# ---------------------------------------------------------------- (6) the pinhole's precision limit

def limit_fov(size):
    """The widest fov_y the pinhole takes at this size: its widest tangent (horizontal when
    wider than tall) is MAX_TANGENT."""
    w, h = size
    return math.degrees(2 * math.atan(MAX_TANGENT * min(1.0, h / w)))


def one_sided(t):
    return {"left": (-t, 1.2, -1.0, 1.0), "right": (-1.2, 1.2, -t, 1.0)}


@pytest.mark.parametrize("size", [(64, 64), (160, 120), (120, 160)])
def test_pinhole_takes_fov_up_to_its_precision_limit_and_refuses_beyond(size):
    fov = limit_fov(size)
    assert fov > 179.998
    StereoRig(fov_y=fov * (1 - 1e-12), size=size)
    with pytest.raises(ValueError, match=r"reaches frustum tangent .*planar projection precision ends at "
                                         r"tangent 1e\+05.*wide-angle camera model"):
        StereoRig(fov_y=fov + 1e-4, size=size)


def test_pinhole_refuses_hmd_tangents_beyond_its_precision_limit():
    StereoRig(eye_tangents=one_sided(MAX_TANGENT))
    with pytest.raises(ValueError, match=r"eye_tangents\['left'\] reach 1\.01e\+05; planar projection precision"):
        StereoRig(eye_tangents=one_sided(1.01 * MAX_TANGENT))
    with pytest.raises(ValueError, match="4 finite numbers"):
        StereoRig(eye_tangents={"left": (-1, 1, float("nan"), 1)})


def test_raster_and_ray_cast_visibility_agree_at_the_pinhole_limit(gl):
    """Both primary visibility paths see the same triangle in >= 99 % of the pixels at the widest
    view the pinhole takes (measured: 99.99 %; beyond 1.5x the limit they drift apart)."""
    from rayvr import Renderer
    from rayvr.renderer import RenderSettings
    from rayvr.scene.loader import load

    scene, size = load(None), (160, 120)
    pose = Pose.look_at([0.3, 1.5, 1.0], [0, 1.2, -1])  # inside the room: every pixel sees a wall
    rigs = [StereoRig(pose, fov_y=limit_fov(size) * (1 - 1e-12), size=size, near=1e-5),
            StereoRig(pose, eye_tangents=one_sided(MAX_TANGENT), size=size, near=1e-5)]
    ids = {}
    for primary in ("raster", "rays"):
        with Renderer(scene, gl=gl, settings=RenderSettings(primary=primary)) as r:
            ids[primary] = [r.render(rig, aux=("triangle",)) for rig in rigs]
    for raster, rays in zip(ids["raster"], ids["rays"]):
        for eye in ("left", "right"):
            a, b = raster.eyes[eye].aux["triangle"], rays.eyes[eye].aux["triangle"]
            assert (b != 0xFFFFFFFF).mean() > 0.9  # not agreement on background
            assert (a == b).mean() >= 0.99, (eye, (a == b).mean())
