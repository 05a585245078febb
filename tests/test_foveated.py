"""The foveated camera's reconstruction for display (frame/cameras/foveated.py reconstruct, its GLSL twin
glsl/shade/sample_resolve.comp) against a dense reference: the pinhole's frame of the same rays,
which has every pixel the foveated frame samples and the ones between."""
from dataclasses import replace

import numpy as np
import pytest

from conftest import quad
from rayvr import Renderer
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Foveated
from rayvr.renderer import RenderSettings
from rayvr.scene.loader import Material, from_arrays

SIZE = (64, 48)
MODEL = Foveated(gaze=(0.15, 0.2), mar_slope=0.1, fovea_radius=2.0)  # sparse away from the gaze


def light_panel_scene():
    """A bright emissive panel (8x the white point, like a ceiling light) tilted across the view,
    in front of a dark grey wall: its edges cross the sparse lattices at every angle."""
    wall_v, wall_f = quad((0.0, 0.0, -4.0), (6.0, 0.0, 0.0), (0.0, 6.0, 0.0))
    panel_v, panel_f = quad((0.4, -0.2, -2.5), (1.1, 0.35, 0.0), (-0.3, 0.8, 0.0))
    return from_arrays(np.concatenate([wall_v, panel_v]), np.concatenate([wall_f, panel_f + 4]),
                       materials=[Material("wall", base_color=(0.05, 0.05, 0.05, 1.0)),
                                  Material("panel", base_color=(0.0, 0.0, 0.0, 1.0), emission=(8.0, 8.0, 8.0))],
                       triangle_material=[0, 0, 1, 1], ambient_lights=False, name="light panel")


def isolated_dark(color: np.ndarray, margin: float) -> np.ndarray:
    """Pixels whose luma is more than `margin` below every one of their 8 neighbours'."""
    luma = color.astype(np.float64).mean(axis=-1)
    h, w = luma.shape
    pad = np.pad(luma, 1, mode="edge")
    neighbours = [pad[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]
    return luma < np.min(neighbours, axis=0) - margin


@pytest.fixture(scope="module")
def frames(gl):
    pose = Pose.look_at([0.0, 0.0, 0.0], [0.0, 0.0, -1.0])
    settings = RenderSettings(primary="rays", ambient=(0.02, 0.02, 0.02), background=(0.0, 0.0, 0.0))
    rig = StereoRig(pose, ipd=0.0, fov_y=70, size=SIZE, camera=MODEL)
    with Renderer(light_panel_scene(), gl=gl, settings=settings) as r:
        fov = r.render(rig, eyes="left", aux=("hdr",))
        ref = r.render(replace(rig, camera="pinhole"), eyes="left", aux=("hdr",))
    return fov.left, ref.left, rig.eye("left")


def test_the_pattern_is_sparse_with_partial_lattices(frames):
    fov, ref, eye = frames
    sample = MODEL.footprint(eye) > 0
    assert 0.2 < sample.mean() < 0.5
    np.testing.assert_array_equal(fov.aux["hdr"][sample], ref.aux["hdr"][sample])  # samples: the pinhole's pixels
    panel = ref.aux["hdr"][..., 0] > 4.0
    assert 0.05 < panel.mean() < 0.5


def test_gpu_fill_equals_the_numpy_twin(frames):
    fov, ref, eye = frames
    sample = MODEL.footprint(eye) > 0
    ref_hdr = ref.aux["hdr"][..., :3].astype(np.float64)
    expected = MODEL.reconstruct(eye, np.where(sample[..., None], ref_hdr, 0.0))
    np.testing.assert_allclose(fov.aux["hdr"][..., :3], expected, rtol=2e-3, atol=2e-3)
    # and it is near the dense frame: edges blur over a lattice cell
    err = np.abs(fov.color.astype(int) - ref.color.astype(int)).max(axis=-1)
    assert err.mean() < 16, err.mean()


def test_no_dark_dots_beside_the_room_light(gl):
    """Issue 20: the default foveated camera left regular single dark dots inside the room's light
    panel and along the mirror's border: samples just outside the light, amid a fill that (from
    the finest cell whose corners were all samples, in linear HDR) ignored them and was white.
    Every isolated dark pixel of the frame must be one the dense frame of the same rays has too."""
    with Renderer(None, None, gl=gl, settings=RenderSettings(primary="rays")) as r:
        rig = StereoRig.for_scene(r.scene, size=(320, 240), camera=Foveated())
        fov = r.render(rig, eyes="left").left
        ref = r.render(replace(rig, camera="pinhole"), eyes="left").left
    sample = Foveated().footprint(rig.eye("left")) > 0
    assert sample.mean() < 0.5
    dots = isolated_dark(fov.color, 64) & ~isolated_dark(ref.color, 32)
    assert not dots.any(), np.argwhere(dots)[:10]


def test_reconstruct_keeps_samples_and_flat_images():
    """Numpy twin, analytic: samples keep their value; a flat image fills flat (the weights are a
    partition of unity on every level); every non-sample pixel inside the image beside a sample
    depends on it. (On the image's border the fill runs along the border, and its last column and
    top row, samples that close the cells, count at the lattice's points.)"""
    eye = StereoRig(Pose(), fov_y=70, size=SIZE, camera=MODEL).eye("left")
    sample = MODEL.footprint(eye) > 0
    flat = MODEL.reconstruct(eye, np.where(sample[..., None], np.full(3, 0.7), 0.0))
    np.testing.assert_allclose(flat, 0.7, rtol=1e-12)
    rng = np.random.default_rng(3)
    img = np.where(sample[..., None], rng.uniform(0.0, 2.0, (*sample.shape, 3)), 0.0)
    base = MODEL.reconstruct(eye, img)
    np.testing.assert_array_equal(base[sample], img[sample])
    inner = np.zeros_like(sample)
    inner[1:-1, 1:-1] = True
    for y, x in np.argwhere(sample & inner):
        bumped = img.copy()
        bumped[y, x] += 1.0
        changed = np.abs(MODEL.reconstruct(eye, bumped) - base).max(axis=-1) > 0
        for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            q = (y + dy, x + dx)
            if inner[q] and not sample[q]:
                assert changed[q], ((y, x), q)
