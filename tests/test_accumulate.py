"""Accumulation (rayvr/frame/accumulation.py, frame/passes/accumulate.py): successive samples of a still view
average to the converged image like 1/sqrt(N), each sample draws its own random sequence, any
change (pose, materials, scene, size, settings) starts over, and temporal reprojection carries the
history of the surface points a moved camera still sees."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from rayvr.frame.accumulation import sample_seed
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import load

# Area-light shadows at one sample a pixel, and a glossy floor: cheap and noisy.
NOISY = {"default": "shadows", "params": {"shadows": {"area_samples": 1}},
         "materials": {"floor": {"effect": "glossy", "samples": 1}, "light": "raster", "ceiling": "raster"}}
SIZE = (32, 24)


# Soft shadows alone: every sample's weight is bounded, so the RMS error's fall is not decided by a
# few GGX fireflies (with the glossy floor it ranged 1.5-2.9x per 4x samples over seed pairs).
SOFT = {"default": "shadows", "params": {"shadows": {"area_samples": 1}}, "materials": {"light": "raster"}}


def _renderer(gl, config=NOISY, **settings):
    return Renderer(load(), parse_config(config, "<noisy>"), gl=gl, settings=RenderSettings(**settings))


def _samples(r) -> np.ndarray:
    """The per-pixel sample counts of the last frame (hdr_accum alpha), surface pixels only."""
    w, h = r._last.gbuffer.size
    a = np.frombuffer(r.resource("hdr_accum").read(), np.float32).reshape(-1, h, w, 4)[..., 3]
    eff = np.frombuffer(r._last.gbuffer.textures["material"].read(), np.uint32).reshape(-1, h, w, 2)[..., 1]
    return a[eff != 255]


def test_accumulated_mean_is_the_mean_of_the_samples_each_with_its_own_seed(gl):
    """spp=4 is the mean of the four frames seeded sample_seed(seed, k): the sequence advances."""
    with _renderer(gl, seed=3) as r:
        rig = StereoRig.for_scene(r.scene, size=SIZE)
        acc = r.render(rig, spp=4, aux=("hdr",))
        singles = []
        for k in range(4):
            r.settings = RenderSettings(seed=sample_seed(3, k))
            singles.append(r.render(rig, aux=("hdr",)).left.aux["hdr"].astype(np.float64))
    assert sample_seed(3, 0) == 3 and len({sample_seed(3, k) for k in range(64)}) == 64
    assert not np.array_equal(singles[0], singles[1])  # the samples differ...
    mean = np.mean(singles, axis=0)
    assert np.allclose(acc.left.aux["hdr"], mean, rtol=1e-5, atol=1e-6)  # ...and average exactly


REF_SPP = 64


def _both(frame) -> np.ndarray:
    """Both eyes' linear colour, clipped as a display would (one firefly must not decide)."""
    return np.clip(np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]]), 0.0, 2.0)


def test_accumulation_converges_like_one_over_sqrt_n(gl):
    with _renderer(gl, SOFT, seed=11) as r:  # the reference draws other samples than the images it judges
        rig = StereoRig.for_scene(r.scene, size=SIZE)
        ref = _both(r.render(rig, spp=REF_SPP, aux=("hdr",)))
    err = {}
    with _renderer(gl, SOFT) as r:
        for n in (1, 4, 16):
            img = _both(r.render(rig, spp=n, aux=("hdr",)))
            err[n] = float(np.sqrt(((img - ref) ** 2).mean()))
    # The reference's own noise adds 1/REF_SPP of a sample's variance: remove it, then the RMS
    # error falls by sqrt(4) per 4x samples (within Monte Carlo spread on ~3500 pixels).
    var1 = err[1] ** 2 / (1 + 1 / REF_SPP)
    pure = {n: np.sqrt(max(e ** 2 - var1 / REF_SPP, 0.0)) for n, e in err.items()}
    assert 1.6 < pure[1] / pure[4] < 2.5, err
    assert 3.0 < pure[1] / pure[16] < 5.2, err


def test_accumulation_counts_while_still_and_resets_on_every_change(gl):
    with _renderer(gl, accumulate=True) as r:
        rig = StereoRig.for_scene(r.scene, size=SIZE)
        for _ in range(3):
            r.render(rig)
        assert r.accumulator.sample == 2 and np.all(_samples(r) == 3)
        moved = replace(rig, pose=Pose(rig.pose.position + np.array([0.05, 0.0, 0.0]), rig.pose.rotation))
        r.render(moved)
        assert r.accumulator.sample == 0 and np.all(_samples(r) == 1), "a pose change starts over"
        r.render(moved)
        assert np.all(_samples(r) == 2)
        r.set_materials(parse_config(NOISY, "<reloaded>"))
        r.render(moved)
        assert np.all(_samples(r) == 1), "a material reload starts over"
        r.render(moved)
        r.update_vertices(r.scene.vertices + np.float32(0.0))
        r.render(moved)
        assert np.all(_samples(r) == 1), "a scene change starts over"
        r.render(moved)
        r.settings = RenderSettings(accumulate=True, exposure=2.0)
        r.render(moved)
        assert np.all(_samples(r) == 1), "a settings change starts over"
        r.render(moved.with_size((40, 30)))
        assert np.all(_samples(r) == 1), "a size change starts over"
        r.settings = RenderSettings()  # accumulation off: every frame is its own
        r.render(moved)
        r.render(moved)
        assert r.accumulator.sample == 0


def test_temporal_reprojection_keeps_the_history_of_what_stays_visible(gl):
    with _renderer(gl, accumulate=True, temporal=True) as r:
        rig = StereoRig.for_scene(r.scene, size=SIZE)
        for _ in range(4):
            r.render(rig, aux=("hdr",))
        step = Pose(rig.pose.position + rig.pose.rotation[:, 0] * 0.03, rig.pose.rotation)
        moved = replace(rig, pose=step)
        carried = r.render(moved, aux=("hdr",))
        n = _samples(r)
        assert r.accumulator.sample == 4
        # Most points stay in view and keep their 4 samples (+1); the disoccluded strip starts over.
        assert (n == 5).mean() > 0.8 and (n == 1).any(), np.unique(n, return_counts=True)
    with _renderer(gl, seed=5) as fresh:  # the converged image at the new pose
        ref = fresh.render(moved, spp=32, aux=("hdr",))
        one = fresh.render(moved, aux=("hdr",))
    # Reprojected history from the right pixels: far closer to the converged image than one sample.
    assert np.abs(_both(carried) - _both(ref)).mean() < 0.7 * np.abs(_both(one) - _both(ref)).mean()
    with _renderer(gl, accumulate=True) as r:  # without temporal reprojection a move starts over
        r.render(rig)
        r.render(moved)
        assert np.all(_samples(r) == 1)
