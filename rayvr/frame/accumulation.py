"""Accumulation of samples while nothing changes: which sample a frame is, and when to start over.

A frame of a sampled effect (area-light shadows, glossy, path, photon) is one sample per pixel.
While the camera, the scene, the material config, the image size and the settings stay as they
were, successive frames draw *new* samples (their random sequence is keyed to the sample index)
and the `accumulate` pass (rayvr/frame/passes/accumulate.py) keeps their running mean, so the image
converges like 1/sqrt(N). Any change starts over at sample 0; with temporal reprojection on
(`RenderSettings.temporal`), a camera move instead carries the history of the pixels that stay
visible (the pass reprojects them and drops the disoccluded ones).

Sample 0 uses `RenderSettings.seed` unchanged, so a single frame is the image it always was;
sample k > 0 uses `sample_seed(seed, k)`. Passes read the frame's seed as `fc.settings.seed`, so
every sampled shader advances with the sample index without knowing about accumulation.
"""
from __future__ import annotations

from dataclasses import astuple, dataclass, replace

import numpy as np

from .pcg import pcg_hash


HISTORY_CAP = 32  # samples a reprojected history counts for at most while the camera moves (Falcor SVGF)


def temporal_problem(camera) -> str | None:
    """Why temporal reprojection (RenderSettings.temporal) cannot follow `camera` (a rayvr.frame.cameras
    model), or None: the accumulate pass reprojects the history through the eyes' planar frusta,
    which only a rasterizable model has (Renderer.plan refuses the others; the preview leaves it off)."""
    if camera.rasterizable:
        return None
    return (f"temporal reprojection reprojects the last frame's samples through the eyes' planar "
            f"frusta, which the {camera.name} camera does not have")


def sample_seed(seed: int, sample: int) -> int:
    """The 32-bit seed of sample `sample` of a sequence seeded `seed` (sample 0: `seed` itself).
    A PCG-style integer hash, so seeds of neighbouring samples and sequences are unrelated."""
    if sample == 0:
        return int(seed) & 0xFFFFFFFF
    v = (int(seed) * 0x9E3779B9 + int(sample) * 0x85EBCA6B + 0x68E31DA4) & 0xFFFFFFFF
    for _ in range(2):
        v = pcg_hash(v)
    return v


@dataclass
class SampleState:
    """What the accumulate pass needs to know about this frame."""

    sample: int  # index of this frame's sample in the running sequence (0: start over)
    reset: bool  # the history is dropped (every pixel starts at this sample)
    moved: bool  # the camera moved with temporal reprojection on: reproject, cap the history
    previous: dict  # the previous frame's camera uniforms (glsl/common/camera.glsl), for reprojection


class Accumulator:
    """Tracks what a frame depends on and counts samples while it stays the same."""

    def __init__(self):
        self._scene_key = None  # everything but the camera
        self._camera = None  # the camera uniforms of the last frame (bytes, for comparison)
        self._camera_values: dict = {}
        self.sample = -1
        self.version = 0  # bumped by Renderer on a scene or material change

    def invalidate(self) -> None:
        """Start over at the next frame (the scene or its materials changed)."""
        self.version += 1

    def next(self, camera_uniforms: dict, other_key, settings, force_sample: int | None = None) -> SampleState:
        """The sample state of a frame seen through `camera_uniforms` (name -> array), whose
        other inputs (plan, size, ...) compare as `other_key`. `force_sample`: this sample index
        (0 starts over) whatever changed, as `render(spp=N)` asks."""
        cam = tuple((k, np.asarray(v).tobytes()) for k, v in sorted(camera_uniforms.items()))
        key = (other_key, self.version, astuple(replace(settings, seed=0)), settings.seed)
        same_scene = key == self._scene_key
        same_camera = cam == self._camera
        previous = self._camera_values
        if force_sample is not None:
            sample = int(force_sample)
            reset, moved = sample == 0, False
        elif same_scene and same_camera and settings.accumulate:
            sample, reset, moved = self.sample + 1, False, False
        elif same_scene and settings.accumulate and settings.temporal:
            sample, reset, moved = self.sample + 1, False, True
        else:
            sample, reset, moved = 0, True, False
        self._scene_key, self._camera, self._camera_values = key, cam, dict(camera_uniforms)
        self.sample = sample
        return SampleState(sample, reset, moved, previous)
