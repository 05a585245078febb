"""A camera model added from outside rayvr (docs/architecture.md, "Add a camera model"): the
orthographic camera of tests/toy_camera/ (its module and its GLSL file; nothing under rayvr/ names
it) is registered, gets its CAMERA_<NAME> id in the header of the programs compiled afterwards,
makes on the GPU the rays its numpy reference makes, and renders through the Renderer (ray-cast
primary visibility, as for any model that is not rasterizable) the triangles and depths Embree
finds along those rays."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from rayvr.frame.cameras import CAMERA_MODELS, CameraModel, Pinhole, register_camera_model, unregister_camera_model
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.gbuffer import NO_HIT
from rayvr.gl import shaders
from rayvr.renderer import Renderer
from rayvr.scene.loader import load

from test_camera_models import _compare
from test_raytrace import embree
from toy_camera.orthographic import Orthographic

INSIDE_THE_ROOM = Pose.look_at([0.3, 1.5, 1.0], [0.0, 1.2, -1.0])  # the default scene: walls in every pixel


@pytest.fixture(scope="module")
def orthographic():
    register_camera_model(Orthographic)
    try:
        yield Orthographic
    finally:
        unregister_camera_model(Orthographic.name)


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
