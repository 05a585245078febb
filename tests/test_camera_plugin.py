"""A camera model added from outside rayvr (docs/architecture.md, "Add a camera model"): the
orthographic camera of tests/toy_camera/ (its module and its GLSL file; nothing under rayvr/ names
it) is registered, gets its CAMERA_<NAME> id in the header of the programs compiled afterwards,
makes on the GPU the rays its numpy reference makes, and renders through the Renderer (ray-cast
primary visibility, as for any model that is not rasterizable) the triangles and depths Embree
finds along those rays. The checkerboard camera of tests/toy_camera/ is a sparse model with its own
fill for display (its GLSL and dispatch steps, its numpy twin), which the frame runs; both models'
parameters reach --camera-param's help from their declarations, and the frame knobs take the one
that declares the pinhole reference judges it."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from rayvr.cli import build_parser
from rayvr.frame.cameras import CAMERA_MODELS, CameraModel, Pinhole, register_camera_model, unregister_camera_model
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.gbuffer import NO_HIT
from rayvr.gl import shaders
from rayvr.quality.frame_knobs import FrameKnobs, cameras, parse_grid
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import load

from test_camera_models import _compare
from test_raytrace import embree
from toy_camera.checkerboard import Checkerboard
from toy_camera.orthographic import Orthographic

INSIDE_THE_ROOM = Pose.look_at([0.3, 1.5, 1.0], [0.0, 1.2, -1.0])  # the default scene: walls in every pixel


@pytest.fixture(scope="module")
def orthographic():
    register_camera_model(Orthographic)
    try:
        yield Orthographic
    finally:
        unregister_camera_model(Orthographic.name)


@pytest.fixture(scope="module")
def checkerboard():
    register_camera_model(Checkerboard)
    try:
        yield Checkerboard
    finally:
        unregister_camera_model(Checkerboard.name)


def header_defines() -> dict:
    return dict(line.split()[1:3] for line in shaders.GENERATED["layout.glsl"]().splitlines()
                if line.startswith("#define ") and len(line.split()) == 3)


def test_a_registered_model_gets_an_id_that_programs_compiled_afterwards_see(orthographic):
    ids = {name: int(header_defines()[f"CAMERA_{name.upper()}"]) for name in CAMERA_MODELS}
    assert sorted(ids.values()) == list(range(1, len(ids) + 1))  # one id each, the next one for the newcomer
    assert list(CAMERA_MODELS)[-1] == "orthographic" and ids["orthographic"] == len(ids)
    defines = orthographic.defines()
    assert defines == {"CAMERA_MODEL": "CAMERA_ORTHOGRAPHIC", "CAMERA_MODEL_FILE": orthographic.glsl,
                       "CAMERA_DEPTH_ALONG_RAY": 0}
    source = shaders.load_source("cameras/camera_rays.comp", defines)
    assert f"#define CAMERA_ORTHOGRAPHIC {ids['orthographic']}" in source.text
    assert source.files[-1] == orthographic.glsl  # the absolute path, included by rayvr's camera.glsl


def test_registration_refuses_bad_models_in_one_line(orthographic, tmp_path):
    @dataclass(frozen=True)
    class Shouting(Pinhole):
        name = "ORTHOGRAPHIC"

    @dataclass(frozen=True)
    class NoFile(CameraModel):
        name = "no_file"
        glsl = str(tmp_path / "missing.glsl")

    @dataclass(frozen=True)
    class Unnamed(Pinhole):
        name = "two words"

    cases = [(dict, TypeError, "camera model dict: not a subclass of rayvr.frame.cameras.CameraModel"),
             (Orthographic, ValueError, "the name 'orthographic' is taken by the registered Orthographic"),
             (Shouting, ValueError, "the name 'ORTHOGRAPHIC' is taken by the registered Orthographic"),
             (NoFile, ValueError, f"camera model 'no_file': its GLSL file {tmp_path / 'missing.glsl'} does not exist"),
             (Unnamed, ValueError, "its name must be an identifier, got 'two words'")]
    for cls, error, message in cases:
        with pytest.raises(error) as e:
            register_camera_model(cls)
        assert message in str(e.value) and "\n" not in str(e.value)
    assert CAMERA_MODELS["orthographic"] is Orthographic and "no_file" not in CAMERA_MODELS


def test_the_models_glsl_rays_match_its_numpy_rays(gl, orthographic):
    rig = StereoRig(INSIDE_THE_ROOM, ipd=0.07, fov_y=60, size=(23, 17), camera=Orthographic(height=1.5))
    _compare(gl, rig, 0, None)
    _compare(gl, rig, 0, (5, 16))
    eye = rig.eye("left")
    heights = (rig.camera.rays(eye).origins - eye.position) @ eye.rotation[:, 1]  # parallel rays from a plane
    assert np.ptp(heights) == pytest.approx(1.5 * 16 / 17)  # the outer rows' centres, half a row in


def test_the_renderer_draws_what_embree_finds_along_the_models_rays(gl, orthographic):
    scene = load(None)
    es = embree(scene.vertices, scene.indices)
    rig = StereoRig(INSIDE_THE_ROOM, ipd=0.07, fov_y=60, size=(40, 30), near=0.01, camera=Orthographic(height=1.5))
    with Renderer(scene, gl=gl) as r:
        frame = r.render(rig, aux=("triangle", "position"))
        passes = set(r.compiled(r.plan(camera=rig.camera)).pass_names)
    assert "primary_rays" in passes and "visibility" not in passes  # not rasterizable: rays cast
    for eye in rig.eyes():
        rays = eye.camera.rays(eye)
        o = (rays.origins - scene.origin + rig.near * rays.directions).reshape(-1, 3).astype(np.float32)
        d = rays.directions.reshape(-1, 3).astype(np.float32)
        hit = es.run(np.ascontiguousarray(o), np.ascontiguousarray(d), output=1)
        expected = np.where(hit["primID"] >= 0, hit["primID"].astype(np.int64), NO_HIT).astype(np.uint32)
        distance = np.where(hit["primID"] >= 0, hit["tfar"] + rig.near, np.inf)  # from the image plane
        image = frame.eyes[eye.name]
        triangle = image.aux["triangle"].reshape(-1)
        assert (expected != NO_HIT).all()  # inside the room every ray meets a wall
        ties = np.abs(image.depth.reshape(-1) - distance) <= 1e-5 * distance  # shared edges, coplanar ones
        same = triangle == expected
        assert (same | ties).mean() >= 0.999 and same.mean() > 0.99
        # the depth along the view axis, which for parallel rays from the eye's plane is the distance
        np.testing.assert_allclose(image.depth.reshape(-1)[same], distance[same], rtol=2e-5)
        np.testing.assert_allclose(image.aux["position"].reshape(-1, 3)[same], (rays.origins.reshape(-1, 3)
                                   + distance[:, None] * rays.directions.reshape(-1, 3))[same], atol=1e-4)


def test_registration_refuses_what_a_sparse_model_or_its_help_lacks_in_one_line(checkerboard):
    @dataclass(frozen=True)
    class Unfilled(Checkerboard):
        name = "unfilled"
        reconstruction = None

    @dataclass(frozen=True)
    class FillOnly(Pinhole):
        name = "fill_only"
        reconstruction = Checkerboard.reconstruction

    @dataclass(frozen=True)
    class Misspelt(Checkerboard):
        name = "misspelt"
        param_syntax = {"parrity": "even|odd"}

    cases = [(Unfilled, "sparse samples need `reconstruction`, the GLSL file that fills the pixels between them"),
             (FillOnly, "a `reconstruction` fills the pixels between sparse samples; declare sparse = True"),
             (Misspelt, "param_syntax names 'parrity', which is none of its parameters (parity)")]
    for cls, message in cases:
        with pytest.raises(ValueError) as e:
            register_camera_model(cls)
        assert message in str(e.value) and "\n" not in str(e.value)
        assert cls.name not in CAMERA_MODELS


def test_the_sparse_models_numpy_twin_keeps_samples_and_averages_the_gaps():
    eye = StereoRig(INSIDE_THE_ROOM, fov_y=60, size=(5, 4), camera=Checkerboard(parity="odd")).eye("left")
    sample = Checkerboard(parity="odd").footprint(eye) > 0
    assert sample.sum() == 10 and not sample[-1, 0]  # GL pixel (0, 0), the bottom-left: x + y even
    assert (sample[:, 1:] != sample[:, :-1]).all() and (sample[1:] != sample[:-1]).all()  # a checkerboard
    flat = Checkerboard().reconstruct(eye, np.where(~sample[..., None], 0.7, 0.0))  # even: the other squares
    np.testing.assert_allclose(flat, 0.7, rtol=1e-12)
    rng = np.random.default_rng(5)
    image = np.where(sample[..., None], rng.uniform(0.0, 4.0, (4, 5, 3)), 0.0)
    out = Checkerboard(parity="odd").reconstruct(eye, image, exposure=2.0)
    np.testing.assert_array_equal(out[sample], image[sample])

    def units(c):  # the fill's: x / (1 + x) of the exposed colour x
        return 2.0 * c / (1.0 + 2.0 * c)

    def mean_of(*pixels):
        return np.mean([units(image[q]) for q in pixels], axis=0)

    assert not sample[1, 2] and not sample[3, 0]
    np.testing.assert_allclose(units(out[1, 2]), mean_of((0, 2), (2, 2), (1, 1), (1, 3)), rtol=1e-12)
    np.testing.assert_allclose(units(out[3, 0]), mean_of((2, 0), (3, 1)), rtol=1e-12)  # a corner: two neighbours


def test_a_sparse_plugin_model_renders_its_own_fill(gl, checkerboard):
    """The frame fills the gaps with the model's reconstruction (its GLSL, its dispatch steps): the
    GPU image equals the numpy twin's fill of the GPU's own samples, which are the pinhole's pixels."""
    settings = RenderSettings(exposure=1.5)
    pinhole_rig = StereoRig(INSIDE_THE_ROOM, ipd=0.07, fov_y=60, size=(41, 30), near=0.01)
    for parity in ("even", "odd"):
        rig = replace(pinhole_rig, camera=Checkerboard(parity=parity))
        with Renderer(load(None), gl=gl, settings=settings) as r:
            frame = r.render(rig, aux=("hdr", "triangle"))
            dense = r.render(pinhole_rig, aux=("hdr",))
            passes = set(r.compiled(r.plan(camera=rig.camera)).pass_names)
        assert {"primary_rays", "sample_resolve"} <= passes and "visibility" not in passes
        for eye in rig.eyes():
            sample = rig.camera.footprint(eye) > 0
            got = frame[eye.name].aux["hdr"][..., :3].astype(np.float64)
            pinhole = dense[eye.name].aux["hdr"][..., :3].astype(np.float64)
            assert sample.mean() == pytest.approx(0.5, abs=0.02)
            np.testing.assert_array_equal(got[sample], pinhole[sample])
            assert (frame[eye.name].aux["triangle"][~sample] == NO_HIT).all()  # no ray between the samples
            expected = rig.camera.reconstruct(eye, np.where(sample[..., None], got, 0.0), exposure=1.5)
            np.testing.assert_allclose(got, expected, rtol=2e-3, atol=2e-3)  # frame_hdr is float16
            assert (got[~sample].max(axis=-1) > 0).all()  # filled, near the pinhole's pixels there
            assert np.abs(got - pinhole).mean() < 0.1 * pinhole.mean()


def test_each_models_parameter_syntax_reaches_the_help(checkerboard, orthographic):
    capture = build_parser()._subparsers._group_actions[0].choices["capture"]
    text = " ".join(capture.format_help().split())
    for part in ("checkerboard parity=even|odd", "orthographic height=VALUE",  # VALUE: no syntax declared
                 "foveated gaze=X,Y fovea_mar=DEG mar_slope=S fovea_radius=DEG", "wide mapping=spherical|equidistant"):
        assert part in text, part
    assert "checkerboard: the pinhole's rays at every other pixel" in text  # its doc, under --camera-model


def test_the_frame_knobs_take_a_model_only_if_it_declares_the_pinhole_judges_it(checkerboard, orthographic):
    assert cameras()[:2] == ("pinhole", "foveated") and "checkerboard" in cameras() and "orthographic" not in cameras()
    assert parse_grid("camera=pinhole,checkerboard") == [FrameKnobs(), FrameKnobs(camera="checkerboard")]
    with pytest.raises(ValueError, match="is not one of pinhole, foveated.*checkerboard .the models the pinhole"):
        parse_grid("camera=orthographic")
