"""The non-planar and sampled camera models (rayvr/frame/cameras/): lens pre-distortion with chromatic
channels and its inverse, sample files, wide fields of view past 180 degrees, foveated sample
counts, thin-lens depth of field, the sub-ray set; every model's GLSL against its numpy rays."""
import math

import numpy as np
import pytest

from rayvr.frame.passes import primary_rays

from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import (CAMERA_MODELS, Distorted, Foveated, Pinhole, ThinLens, Wide, get_camera_model,
                           parse_camera_params)
from rayvr.frame.cameras.base import pixel_grid
from rayvr.frame.cameras.distorted import load_samples, write_samples
from rayvr.frame.cameras.foveated import dither_rank
from rayvr.frame.cameras.sampling import SAMPLE_COUNTS, subsamples

from test_cameras import glsl_rays

POSE = Pose.look_at([0.3, 1.4, 2.0], [-0.2, 1.0, -1.0])


def rig_for(model, size=(23, 17), fov=90.0, **kw):
    return StereoRig(POSE, ipd=0.07, fov_y=fov, size=size, camera=model, **kw)


MODELS = {
    "pinhole": lambda: rig_for(Pinhole()),
    "distorted": lambda: rig_for(Distorted(center=(0.05, -0.02))),
    # the shipped lens has k3 = 0: a GLSL term of the wrong power of r would pass without this one
    "distorted_k3": lambda: rig_for(Distorted(coefficients=((0.1, 0.05, 0.08), (0.12, 0.06, 0.11), (0.14, 0.07, 0.15)),
                                              center=(0.05, -0.02))),
    "wide_spherical": lambda: rig_for(Wide(fov_x=210), fov=130),
    "wide_equidistant": lambda: rig_for(Wide(mapping="equidistant"), fov=200),
    "foveated": lambda: rig_for(Foveated(gaze=(0.3, 0.6), mar_slope=0.4, fovea_radius=2.0), size=(40, 30)),
    "dof": lambda: rig_for(ThinLens(aperture=0.05, focus=1.5)),
}


# ---------------------------------------------------------------- GLSL == numpy, every model

def _compare(gl, rig, channel, subsample):
    origin = np.array([0.5, -1.0, 2.0])
    out, flags = glsl_rays(gl, rig, origin, channel, subsample)
    for i, eye in enumerate(rig.eyes()):
        rays = rig.camera.rays(eye, channel, subsample)
        valid = flags[i, ..., 0] == 1.0
        np.testing.assert_array_equal(valid, rays.valid)
        np.testing.assert_allclose(flags[i, ..., 1], rig.camera.footprint(eye, channel), rtol=1e-5)
        v = rays.valid
        np.testing.assert_allclose(out[i, :, :, 0][v], (rays.origins - origin)[v], atol=2e-6)
        np.testing.assert_allclose(out[i, :, :, 1][v], rays.directions[v], atol=2e-6)
        # The neighbours are the rays one footprint step right / up, through the same lens point ...
        f = rig.camera.footprint(eye, channel)
        step = np.maximum(f, 1.0)
        off, lens = (np.zeros(2), np.zeros(2)) if subsample is None else (a[subsample[0]] for a in subsamples(subsample[1]))
        x, y = pixel_grid(eye.size)
        x, y = x + off[0] * step, y + off[1] * step
        for k, (nx, ny) in ((2, (x + step, y)), (3, (x, y + step))):
            ref = rig.camera.ray_at(eye, channel, nx, ny, lens)[1]
            np.testing.assert_allclose(out[i, :, :, k][v], ref[v], atol=2e-6)
        # ... so, to first order, the direction plus its footprint (GL up = minus ddy).
        if rig.camera.name != "distorted" or rig.camera.samples is None:  # a table's bilinear patches have kinks
            bound = 4 * max(np.abs(rays.ddx).max(), np.abs(rays.ddy).max()) ** 2 + 1e-5
            assert np.abs(out[i, :, :, 2] - (rays.directions + rays.ddx))[v].max() < bound
            assert np.abs(out[i, :, :, 3] - (rays.directions - rays.ddy))[v].max() < bound
        assert not np.isnan(out[i][v]).any()


@pytest.mark.parametrize("name", MODELS)
def test_glsl_rays_match_numpy_for_every_model(gl, name):
    rig = MODELS[name]()
    for channel in range(rig.camera.channels):
        _compare(gl, rig, channel, None)
    _compare(gl, rig, rig.camera.channels - 1, (5, 16))  # a sub-ray: footprint offset and lens point


def test_every_registered_model_is_tested():
    assert {n.split("_")[0] for n in MODELS} == set(CAMERA_MODELS)


def test_subsample_set_is_low_discrepancy_and_centred_at_1x():
    for n in SAMPLE_COUNTS:
        off, lens = subsamples(n)
        assert off.shape == lens.shape == (n, 2)
        assert (np.abs(off) < 0.5).all() and (np.hypot(*lens.T) <= 1 + 1e-12).all()
        assert len({tuple(p) for p in off}) == n  # distinct
        # Each column and row band of width 1/n holds exactly one offset (a Hammersley set).
        for axis in range(2):
            bands = np.floor((off[:, axis] + 0.5) * n).astype(int)
            assert sorted(bands) == list(range(n))
    off, lens = subsamples(1)
    assert np.array_equal(off, [[0, 0]]) and np.array_equal(lens, [[0, 0]])
    with pytest.raises(ValueError, match="one of 1, 4, 8, 16, 32"):
        subsamples(3)


# ---------------------------------------------------------------- lens pre-distortion

def test_distortion_and_its_inverse_round_trip_over_the_lens():
    model = Distorted(center=(0.1, -0.05))
    assert model.channels == 3
    g = np.linspace(-1.6, 1.6, 81)  # the whole panel of a 100-degree eye and beyond
    q = np.stack(np.meshgrid(g, g), axis=-1)
    for ch in range(3):
        u = model.distort(q, ch, model.center)
        assert np.abs(model.undistort(u, ch, model.center) - q).max() < 1e-6
        assert np.abs(model.distort(model.undistort(q, ch, model.center), ch, model.center) - q).max() < 1e-6
    # Chromatic: blue is bent most, and off-centre the three channels' rays differ.
    r = [np.linalg.norm(model.distort(q, ch, model.center) - model.center, axis=-1)[0, 0] for ch in range(3)]
    assert r[0] < r[1] < r[2]


def test_each_coefficient_is_its_own_power_of_the_radius():
    """The rays' view tangents against the polynomial written out term by term, one coefficient at a
    time: the pixel centre's panel tangent q (the pinhole's), u = c + (q - c)(1 + k r^(2n))."""
    size = (11, 9)
    for n in (1, 2, 3):
        k = [0.0, 0.0, 0.0]
        k[n - 1] = 0.3
        rig = rig_for(Distorted(coefficients=tuple(k), center=(0.1, -0.05)), size=size)
        for eye in rig.eyes():
            l, r, b, t = eye.tangents
            x, y = np.meshgrid(np.arange(size[0]) + 0.5, np.arange(size[1]) + 0.5)
            q = np.stack([l + x / size[0] * (r - l), t - y / size[1] * (t - b)], axis=-1)  # rows top-down
            c = rig.camera.lens_center(eye)
            radius = np.linalg.norm(q - c, axis=-1, keepdims=True)
            u = c + (q - c) * (1.0 + 0.3 * radius ** (2 * n))
            d = rig.camera.rays(eye, 0).directions @ eye.rotation  # world -> eye space
            np.testing.assert_allclose(d[..., :2] / -d[..., 2:], u, rtol=1e-9, atol=1e-12)


def test_one_coefficient_triple_is_one_channel_set():
    model = Distorted(coefficients=(0.2, 0.1))
    assert model.channels == 1 and model.coefficients == ((0.2, 0.1, 0.0),) * 3


def test_distortion_that_folds_over_the_panel_is_refused():
    with pytest.raises(ValueError, match=r"lens polynomial of every channel .* folds over at radius .* no inverse"):
        rig_for(Distorted(coefficients=(-0.5, 0.0, 0.0)))
    with pytest.raises(ValueError, match="coefficients must be finite"):
        Distorted(coefficients=(float("nan"), 0, 0))


def test_right_eye_lens_centre_is_mirrored():
    rig = rig_for(Distorted(center=(0.1, 0.02)))
    left, right = rig.eyes()
    assert list(rig.camera.lens_center(left)) == [0.1, 0.02] and list(rig.camera.lens_center(right)) == [-0.1, 0.02]


def test_sample_file_reproduces_the_model_it_was_written_from(tmp_path):
    parametric = Distorted()
    rig = rig_for(parametric, size=(12, 9))
    eye = rig.eye("left")
    dirs = np.stack([parametric.rays(eye, ch).directions @ eye.rotation for ch in range(3)])  # eye space
    valid = np.ones((3, 9, 12), bool)
    valid[2, 4, 5] = False  # one blue subpixel without a sample
    path = tmp_path / "lens.txt"
    write_samples(path, dirs, valid)
    table = Distorted(samples=str(path))
    assert table.channels == 3
    rig2 = rig_for(table, size=(12, 9))
    for ch in range(3):
        rays = table.rays(rig2.eye("left"), ch)
        np.testing.assert_array_equal(rays.valid, valid[ch])
        np.testing.assert_allclose(rays.directions[valid[ch]], parametric.rays(eye, ch).directions[valid[ch]], atol=1e-12)
    with pytest.raises(ValueError, match=r"covers 12x9 pixels, the eye image is 13x9: render at 12x9"):
        rig_for(table, size=(13, 9))


def test_sample_file_on_the_gpu_matches_numpy(gl, tmp_path):
    rig = rig_for(Distorted(), size=(10, 7))
    eye = rig.eye("left")
    dirs = np.stack([rig.camera.rays(eye, ch).directions @ eye.rotation for ch in range(3)])
    valid = np.ones((3, 7, 10), bool)
    valid[1, 2:4, 3] = False
    write_samples(tmp_path / "s.txt", dirs, valid)
    table_rig = rig_for(Distorted(samples=str(tmp_path / "s.txt")), size=(10, 7))
    for ch in range(3):
        _compare(gl, table_rig, ch, None)
        _compare(gl, table_rig, ch, (3, 8))


@pytest.mark.parametrize("text, message", [
    ("0 0 0 0 0 -1\n1 0 0 0 0\n", r":2: expected 6 values"),
    ("0 0 x 0 0 -1\n", r":1: channel must be 0, 1, 2 or r, g, b"),
    ("0 0 0 0 0 0\n", r":1: direction \(0, 0, 0\) must be finite and non-zero"),
    ("0 0 0 0 0 -1\n0 0 0 0 1 -1\n", r":2: pixel \(0, 0\) channel 0 again \(first on line 1\)"),
    ("0 0 0 0 0 nan\n", "must be finite"),
    ("-1 0 0 0 0 -1\n", "negative"),
    ("0 0 0 0 0 -1\n0 0 1 0 0 -1\n", r"channels \[0, 1\]"),
    ("# nothing\n", "has no samples"),
])
def test_bad_sample_files_get_one_clear_line(tmp_path, text, message):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as exc:
        load_samples(path)
    assert str(path) in str(exc.value) and "\n" not in str(exc.value)


# ---------------------------------------------------------------- wide field of view

@pytest.mark.parametrize("mapping, fov_x, fov_y", [("spherical", 180, 130), ("spherical", 210, 130),
                                                   ("equidistant", 180, 180), ("equidistant", 210, 130)])
def test_wide_fov_has_no_nan_and_covers_the_expected_solid_angle(mapping, fov_x, fov_y):
    model = Wide(mapping=mapping, fov_x=fov_x)
    rig = rig_for(model, size=(210, 130), fov=fov_y)
    eye = rig.eye("left")
    rays = model.rays(eye)
    assert rays.valid.all()
    for a in (rays.directions, rays.ddx, rays.ddy):
        assert np.isfinite(a).all()
    np.testing.assert_allclose(np.linalg.norm(rays.directions, axis=-1), 1.0, atol=1e-12)
    # Sum of the pixels' solid angles (|ddx x ddy|) against the analytic / finely integrated total.
    covered = np.linalg.norm(np.cross(rays.ddx, rays.ddy), axis=-1).sum()
    expected = model.solid_angle(eye)
    assert abs(covered - expected) / expected < 2e-3, (covered, expected)
    if fov_x > 180:  # past the side: some rays point backwards
        assert (rays.directions @ POSE.forward).min() < 1e-6


def test_wide_fov_field_and_refusals():
    assert math.isclose(Wide(fov_x=360).solid_angle(rig_for(Wide(fov_x=360), fov=180).eye("left")), 4 * math.pi)
    with pytest.raises(ValueError, match="spherical mapping spans at most 180 degrees of pitch"):
        rig_for(Wide(), fov=200)
    with pytest.raises(ValueError, match="not eye_tangents"):
        StereoRig(camera=Wide(), eye_tangents={"left": (-1, 1, -1, 1)})
    with pytest.raises(ValueError, match=r"fov_y must be in \(0, 180\) degrees for a planar projection.*\(wide\)"):
        rig_for(Pinhole(), fov=200)
    rig_for(Wide(mapping="equidistant"), fov=240)  # accepted: past 180 is what it is for


def test_equidistant_past_180_degrees_makes_no_ray():
    model = Wide(mapping="equidistant", fov_x=360)
    rays = model.rays(rig_for(model, size=(40, 40), fov=360).eye("left"))
    corner, centre = rays.valid[0, 0], rays.valid[20, 20]
    assert centre and not corner and np.isfinite(rays.directions).all()


# ---------------------------------------------------------------- foveated

def test_dither_ranks_nest_the_power_of_two_lattices():
    x, y = np.meshgrid(np.arange(64), np.arange(64))
    rank = dither_rank(x, y)
    assert sorted(rank.ravel()) == list(range(4096))
    for k in range(7):
        lattice = (x % (1 << k) == 0) & (y % (1 << k) == 0)
        np.testing.assert_array_equal(rank < 4096 >> (2 * k), lattice)


@pytest.mark.parametrize("gaze", [(0.5, 0.5), (0.2, 0.7)])
def test_foveated_sample_counts_match_the_density_integral(gaze):
    model = Foveated(gaze=gaze, mar_slope=0.03, fovea_radius=3.0)
    eye = rig_for(model, size=(256, 192), fov=100).eye("left")
    # The density model integrated over the image (less its last column and top row, which are
    # always sampled) by a 4x4 midpoint rule per pixel.
    sub = (np.arange(4) + 0.5) / 4
    x = (np.arange(255)[:, None] + sub).ravel()[None, :]
    y = (np.arange(191)[:, None] + sub).ravel()[:, None]
    integral = model.density_at(eye, x, y).sum() / 16
    count = (model.footprint(eye)[1:, :-1] > 0).sum()
    assert 0.05 < count / (256 * 192) < 0.6  # a real saving, not all or nothing
    assert abs(count - integral) / integral < 0.02, (count, integral)
    # Full density at the gaze, every 64th pixel each way always sampled.
    f = model.footprint(eye)
    gx, gy = int(gaze[0] * 256), int(gaze[1] * 192)
    assert (f[gy - 2:gy + 3, gx - 2:gx + 3] == 1).all()
    assert (f[::-1][::64, ::64] > 0).all()


@pytest.mark.parametrize("tangents", [None, (-1.9, 0.6, -0.7, 1.3)], ids=["symmetric", "off_axis_non_square"])
def test_foveated_pixel_angle_is_the_root_of_the_pixels_exact_solid_angle(tangents):
    """With one MAR everywhere (mar_slope 0) the density is (pixel angle / MAR)^2, so density x MAR^2
    is the pixel's solid angle in square degrees: against the exact solid angle of the pixel's
    rectangle on the image plane (the sum of atan(x y / sqrt(1 + x^2 + y^2)) over its corners),
    independent of the model's cos^3 form. An exponent of the wrong power, or a step taken along x
    alone (off-axis, non-square pixels), fails it."""
    import dataclasses

    mar = 8.0  # degrees: the densities stay inside (1/4096, 1), unclamped
    model = Foveated(fovea_mar=mar, mar_slope=0.0, fovea_radius=0.0)
    eye = rig_for(model, size=(40, 30), fov=100).eye("left")
    if tangents is not None:
        eye = dataclasses.replace(eye, tangents=tangents)
    (w, h), (l, r, b, t) = eye.size, eye.tangents
    xs, ys = l + (r - l) * np.arange(w + 1) / w, b + (t - b) * np.arange(h + 1) / h

    def corner(x, y):
        return np.arctan(x * y / np.sqrt(1 + x * x + y * y))
    X, Y = np.meshgrid(xs, ys)  # GL rows: y grows upward
    F = corner(X, Y)
    solid = F[1:, 1:] - F[1:, :-1] - F[:-1, 1:] + F[:-1, :-1]  # steradians, (h, w) bottom-up
    exact = np.degrees(np.sqrt(solid)) ** 2
    x, y = (np.arange(w) + 0.5)[None, :], (np.arange(h) + 0.5)[:, None]
    density = model.density_at(eye, x, y)
    assert (density > 1 / 4096).all() and (density < 1).all()
    np.testing.assert_allclose(density * mar ** 2, exact, rtol=2e-3)


def test_foveated_reconstruction_fills_between_samples():
    model = Foveated(mar_slope=0.1, fovea_radius=2.0)
    eye = rig_for(model, size=(64, 48)).eye("left")
    y, x = np.mgrid[0:48, 0:64]
    # Linear in the fill's units y = x / (1 + x) of the colour x (frame/cameras/foveated.py): exact there.
    linear = np.stack([0.2 + 0.01 * x, 0.2 + 0.005 * y, 0.3 + 0.0 * x], axis=-1)
    smooth = linear / (1.0 - linear)
    sample = model.footprint(eye) > 0
    assert 0.1 < sample.mean() < 0.9
    out = model.reconstruct(eye, np.where(sample[..., None], smooth, 0.0))
    np.testing.assert_allclose(out, smooth, rtol=1e-9)


# ---------------------------------------------------------------- thin lens

def test_dof_with_zero_aperture_is_the_pinhole():
    eye = rig_for(ThinLens(aperture=0.0, focus=3.0)).eye("right")
    pin = Pinhole().rays(eye)
    for sub in (None, (0, 1), (7, 16), (31, 32)):
        rays = eye.camera.rays(eye, 0, sub)
        ref = Pinhole().rays(eye, 0, sub) if sub else pin
        np.testing.assert_allclose(rays.directions, ref.directions, atol=1e-14)
        np.testing.assert_array_equal(rays.origins, ref.origins)


def test_dof_sub_rays_meet_at_the_focus_distance_and_share_lens_points_across_eyes():
    model = ThinLens(aperture=0.1, focus=2.5)
    rig = rig_for(model)
    left, right = rig.eyes()
    _, lens = subsamples(16)
    for i in (1, 5, 11):
        a, b = model.rays(left, 0, (i, 16)), model.rays(left, 0, (0, 16))
        pa = a.origins + a.directions * (2.5 / (a.directions @ POSE.forward))[..., None]
        pc = left.position + Pinhole().rays(left, 0, (i, 16)).directions * 1.0
        assert np.abs((pa - left.position) @ POSE.forward - 2.5).max() < 1e-12  # on the focus plane
        # Same sub-ray, both eyes: the same lens offset from each eye's centre.
        ra = model.rays(right, 0, (i, 16))
        np.testing.assert_allclose(a.origins - left.position, ra.origins - right.position, atol=1e-15)
        expected = 0.1 * (lens[i][0] * POSE.rotation[:, 0] + lens[i][1] * POSE.rotation[:, 1])
        np.testing.assert_allclose(a.origins[0, 0] - left.position, expected, atol=1e-15)
        assert pc.shape == pa.shape and b.origins.shape == a.origins.shape
    no_ipd = StereoRig(POSE, ipd=0.0, fov_y=90, size=(23, 17), camera=model)
    l0, r0 = (model.rays(e, 0, (3, 8)) for e in no_ipd.eyes())
    assert np.array_equal(l0.directions, r0.directions) and np.array_equal(l0.origins, r0.origins)


# ---------------------------------------------------------------- parameters

def test_camera_parameters_from_text():
    assert parse_camera_params("dof", ["aperture=0.02", "focus=3"]) == {"aperture": 0.02, "focus": 3.0}
    assert parse_camera_params("distorted", ["coefficients=0.1,0.2/0.2,0.3/0.3,0.4"])["coefficients"] == \
        ((0.1, 0.2), (0.2, 0.3), (0.3, 0.4))
    assert parse_camera_params("wide", ["mapping=equidistant", "fov_x=210"]) == {"mapping": "equidistant", "fov_x": 210.0}
    assert parse_camera_params("foveated", ["gaze=0.4,0.5"]) == {"gaze": (0.4, 0.5)}
    with pytest.raises(ValueError, match="the dof camera has no parameter 'blur'; allowed: aperture, focus"):
        parse_camera_params("dof", ["blur=1"])
    with pytest.raises(ValueError, match="expected KEY=VALUE with KEY one of aperture, focus"):
        parse_camera_params("dof", ["focus"])
    with pytest.raises(ValueError, match="cannot read 'x' as a number"):
        parse_camera_params("dof", ["focus=x"])
    with pytest.raises(ValueError, match="has no parameter 'focus'; allowed: mapping, fov_x"):
        get_camera_model("wide", focus=2)


def test_the_frame_reads_camera_capabilities_from_the_model_not_its_name(monkeypatch):
    """Planarity (the quadtree's screen-space tracing, render tiles, reprojection) and the tile
    culling default are the model's declarations: a planar model under another name gets what the
    pinhole gets, and a model that declines tile culling does not get it by default."""
    from dataclasses import dataclass

    from rayvr.frame.cameras import CAMERA_MODELS, Pinhole
    from rayvr.frame.graph import FramePlan
    from rayvr.frame.passes.quadtree import QuadtreePass, QuadtreeVisitsPass
    from rayvr.renderer import RenderSettings

    @dataclass(frozen=True)
    class PlanarCopy(Pinhole):  # as a model registered from outside rayvr would be
        name = "planar_copy"

    @dataclass(frozen=True)
    class Untiled(Pinhole):
        name = "untiled"
        culls_tiles_by_default = False

    for model in (PlanarCopy, Untiled):
        monkeypatch.setitem(CAMERA_MODELS, model.name, model)
    assert primary_rays.culls_tiles(RenderSettings(msaa=4), "planar_copy")
    assert not primary_rays.culls_tiles(RenderSettings(msaa=4), "untiled")
    for camera, planar in (("planar_copy", True), ("pinhole", True), ("wide", False), ("foveated", False)):
        plan = FramePlan(effects=frozenset({"ssr"}), view="quadtree_visits", camera=camera)
        assert (QuadtreePass().why(plan) is not None) == planar, camera
        assert (QuadtreeVisitsPass().why(plan) is not None) == planar, camera


def test_a_model_registered_outside_rayvr_gets_its_declared_behaviour(monkeypatch, gl):
    """Every capability the frame, the CLI and the camera files read is the model's declaration:
    models declared here, named like none of rayvr's, are refused --convergence, --temporal and
    --aperture (pointing to their own lens parameter), write ray-distance depth into transforms.json
    and have no nerfstudio camera unless they say which; a planar copy of the pinhole keeps all."""
    import argparse
    from dataclasses import dataclass

    from rayvr import Renderer
    from rayvr.frame.cameras.base import CameraModel
    from rayvr.commands.args import camera_from_args
    from rayvr.renderer import RenderSettings
    from rayvr.app.views import camera_record

    @dataclass(frozen=True)
    class Angular(Pinhole):  # as a model registered from outside rayvr would be
        name = "angular"
        rasterizable = False
        converges = False
        depth_along_ray = True
        lens_parameter = "iris"

        def transforms_fields(self, eye):
            raise self.not_described("it is made up for a test")

    @dataclass(frozen=True)
    class PlanarCopy(Pinhole):
        name = "planar_copy"

    @dataclass(frozen=True)
    class RayDepth(Pinhole):
        name = "ray_depth"
        depth_along_ray = True

    @dataclass(frozen=True)
    class Bare(CameraModel):
        name = "bare"

    for model in (Angular, PlanarCopy, RayDepth, Bare):
        monkeypatch.setitem(CAMERA_MODELS, model.name, model)

    def flags(model):
        return argparse.Namespace(camera_model=model, camera_param=None, convergence=2.0, msaa=1, primary=None)
    with pytest.raises(ValueError, match="--convergence .* the angular camera's eyes have none"):
        camera_from_args(flags("angular"))
    assert isinstance(camera_from_args(flags("planar_copy")), PlanarCopy)

    with Renderer(gl=gl, settings=RenderSettings(accumulate=True, temporal=True)) as r:
        with pytest.raises(ValueError, match="temporal reprojection .* the angular camera does not have"):
            r.plan(camera=Angular())
        assert r.plan(camera=PlanarCopy()).accumulate
    with Renderer(gl=gl, settings=RenderSettings(dof_diameter=0.1)) as r:
        with pytest.raises(ValueError, match="the angular camera is not a pinhole: use its iris parameter"):
            r.plan(camera=Angular())
        assert r.plan(camera=PlanarCopy()).dof

    rig = StereoRig(POSE, fov_y=60, size=(8, 6), camera=PlanarCopy())
    record = camera_record(rig.eye("left"))
    assert record["camera_model"] == "OPENCV" and "view depth along -Z" in record["convention"]
    angular_eye = StereoRig(POSE, fov_y=60, size=(8, 6), camera=Angular()).eye("left")
    with pytest.raises(ValueError, match="cannot describe the angular camera: it is made up for a test"):
        camera_record(angular_eye)
    ray_depth_eye = StereoRig(POSE, fov_y=60, size=(8, 6), camera=RayDepth()).eye("left")
    assert "distance along each pixel's ray" in camera_record(ray_depth_eye)["convention"]
    with pytest.raises(ValueError, match="cannot describe the bare camera: no camera_model is written for it"):
        Bare().transforms_fields(angular_eye)
