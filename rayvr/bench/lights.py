"""`rayvr bench lights`: next-event estimation by power (`--light-picks K`, rayvr/scene/
light_selection.py) against lighting every surface with every light, at equal time, on the bench
scenes with ADDED_LIGHTS point lights added (seeded: inside the heads' region, 0.3-2.5 m above
the floor, intensities over two decades), `shadows` on every material (the shadow rays are what K
changes).

Per scene, head pose (the bench view and `poses` heads of rayvr/bench/head_poses.py, content and
random) and K
in PICKS (0: every light):
  - `ms`: GPU ms of the frame, both eyes (median over `repeat` frames after the warm-up);
  - `mse`: the mean squared error of one frame's displayed colour (tonemapped, 0..1: a light next
    to a surface makes a hot spot whose linear value swamps every other pixel's error) against the
    converged frame of every light (the mean of `reference_frames` frames, seeds of their own),
    over `frames` frames of other seeds (K = 0's is the noise of the area lights and of the
    sample positions within each pixel alone);
  - `equal_time_mse`: mse x ms / K = 0's ms: the error of as many accumulated frames as the frame of
    every light takes to render (an accumulated frame's MSE falls as 1 / frames). Below K = 0's
    mse: at equal time the picks make the better image.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..gl.context import create_context
from ..renderer import Renderer, RenderSettings
from ..scene.loader import Light
from ..scene.materials import parse_config
from .head_poses import POSE_SEED, draw_poses, pose_bounds
from .rays import time_frame
from .report import device_meta, write_report
from .scenes import bench_scenes

ADDED_LIGHTS = 64
POSES = 8  # heads beside the bench view unless --poses says
PICKS = (0, 1, 4, 16)
REFERENCE_SEED = 10_000  # the reference's seeds start here; the variants' at 0


def add_lights(scene, name: str, count: int, seed: int = 1) -> None:
    """`count` point lights spread through scene `name`'s head region (bench/head_poses.py)."""
    bounds = pose_bounds(scene, name)
    rng = np.random.default_rng(seed)
    floor = bounds["y"][0] - 1.5  # the heads' eye heights start 1.5 m above the floor
    for _ in range(count):
        x, z = (float(rng.uniform(*bounds[a])) for a in ("x", "z"))
        y = floor + float(rng.uniform(0.3, 2.5))
        scene.lights.append(Light("point", color=tuple(float(c) for c in rng.uniform(0.4, 1.0, 3)),
                                  intensity=float(10 ** rng.uniform(-1.0, 1.0)), position=(x, y, z),
                                  source="bench lights"))


def displayed(r, rig, seed: int) -> np.ndarray:
    """Both eyes' displayed colour (0..1) of the frame of `seed`."""
    r.settings = replace(r.settings, seed=int(seed))
    f = r.render(rig)
    return np.stack([f.left.color[..., :3], f.right.color[..., :3]]).astype(np.float64) / 255.0


def run(out_dir: Path, size=(1440, 1600), scenes=("default", "sponza"), poses: int = POSES, repeat: int = 10,
        frames: int = 4, reference_frames: int = 8, picks=PICKS, backend=None, progress: bool = True,
        pose_seed: int = POSE_SEED) -> dict:
    gl = create_context(backend)
    rows, skipped = [], {}
    config = parse_config({"default": "shadows"}, "bench:lights")
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            own = len(scene.lights)
            add_lights(scene, name, ADDED_LIGHTS)
            drawn = draw_poses(scene, name, poses, pose_seed) if poses else []
            heads = [("bench view", "fixed", rig.pose)] + [(f"head {h.index}", h.kind, h.pose) for h in drawn]
            with Renderer(scene, config, gl=gl, settings=RenderSettings(light_picks=0)) as r:
                for where, kind, pose in heads:
                    rig.pose = pose
                    r.settings = replace(r.settings, light_picks=0)
                    reference = np.mean([displayed(r, rig, REFERENCE_SEED + i) for i in range(reference_frames)], axis=0)
                    base_ms = None
                    for k in picks:
                        r.settings = replace(r.settings, light_picks=k, seed=0)
                        _, passes, ms = time_frame(r, rig, repeat, 3)
                        base_ms = ms if k == 0 else base_ms
                        mse = float(np.mean([np.mean((displayed(r, rig, i) - reference) ** 2) for i in range(frames)]))
                        row = {"scene": name, "pose": where, "pose_kind": kind, "light_picks": k,
                               "lights": len(scene.lights), "scene_lights": own, "ms": ms,
                               "rt_shadows_ms": passes.get("rt_shadows"), "mse": mse,
                               "equal_time_mse": mse * ms / base_ms if base_ms else None}
                        rows.append(row)
                        if progress:
                            print(f"  {name:7s} {where:10s} K={k:2d}: {ms:7.3f} ms, mse {mse:.3e}, "
                                  f"at equal time {row['equal_time_mse']:.3e}", flush=True)
        meta = {**device_meta(gl.info()), "bench": "lights", "per_eye_size": list(size), "repeat": repeat,
                "frames": frames, "reference_frames": reference_frames, "added_lights": ADDED_LIGHTS,
                "poses": poses, "pose_seed": pose_seed, "skipped": skipped, "timings_meaningful": not gl.is_software,
                "config": "shadows on every material"}
        result = {"meta": meta, "rows": rows}
        write_report(out_dir, "lights", result)
    finally:
        gl.release()
    return result
