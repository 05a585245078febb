"""`rayvr bench motion`: the trade judged along head motion instead of on still frames.

Per scene, head trajectory (rayvr/bench/trajectories.py: slow looks, fast turns, walks, glances,
at 90 and 120 Hz, from the scene's content poses) and variant (render settings on top of the
scene's benchmark config, and `spp`, the samples a frame accumulates: one sample a pixel raw, and
denoised, by default), every frame of the
trajectory is rendered and judged against that frame's own reference (the same config and pose
accumulated over `reference_spp` samples, with its own seed: a reference and the variant it judges
never share one; quality/motion_error.py):
  - mean FLIP per frame (both eyes): its mean over the trajectory and its worst frame;
  - flicker: how far the frames' frame-to-frame change departs from the references' (the
    shimmer a headset shows), mean and worst transition;
  - the noise floor: the first frame's reference against a second reference of another seed;
  - GPU ms per frame (timer sums; they mean nothing on a software rasterizer: the meta says so).
Temporal reuse along the motion is not in it yet: each frame is rendered from a fresh start.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..gl.context import create_context
from ..quality.metrics import flip
from ..quality.motion_error import flicker
from ..renderer import Renderer
from .head_poses import POSE_SEED
from .report import device_meta, write_report
from .scenes import bench_scenes
from .stereo import bench_config
from .trajectories import KINDS, RATES_HZ, SECONDS, draw_trajectories

VARIANTS = {"1 spp": {}, "1 spp denoised": {"denoise": True}}
REFERENCE_SPP = 64
REFERENCE_SEED = 1000  # the references' seed; the variants render with seed 0
FLOOR_SEED = 2000  # the second reference of the noise floor


def _both(frame) -> np.ndarray:
    return np.concatenate([np.asarray(frame.left.color), np.asarray(frame.right.color)], axis=1)[..., :3]


def trajectory_rows(r: Renderer, rig, name: str, traj, variants: dict, reference_spp: int, progress=True) -> list:
    """One row per variant for trajectory `traj` of scene `name` through `rig`'s eyes and camera."""
    base = r.settings
    rows = []
    try:
        r.settings = replace(base, seed=REFERENCE_SEED)
        rigs = [replace(rig, pose=p) for p in traj.poses]
        refs = [_both(r.render(q, spp=reference_spp)) for q in rigs]
        r.settings = replace(base, seed=FLOOR_SEED)
        floor = flip(refs[0], _both(r.render(rigs[0], spp=reference_spp)), float_encoding="srgb")
        for label, fields in variants.items():
            # spp: the samples a frame accumulates, not a setting
            r.settings = replace(base, **{"seed": 0, **{k: v for k, v in fields.items() if k != "spp"}})
            frames, ms = [], []
            for q in rigs:
                f = r.render(q, spp=fields.get("spp", 1))
                frames.append(_both(f))
                ms.append(sum(f.timings.values()) if f.timings else float("nan"))
            flips = np.array([flip(a, b, float_encoding="srgb") for a, b in zip(refs, frames)])
            flick = flicker(refs, frames, float_encoding="srgb")
            timed = np.isfinite(ms).any()
            rows.append({"scene": name, "trajectory": traj.kind, "rate_hz": traj.rate_hz,
                         "anchor": traj.anchor.to_dict(), "frames": len(frames), "seconds": traj.times[-1],
                         "variant": label, "settings": fields, "mean_flip": float(flips.mean()),
                         "worst_flip": float(flips.max()), "worst_frame": int(flips.argmax()),
                         "flicker": float(flick.mean()), "worst_flicker": float(flick.max()),
                         "noise_floor_flip": floor, "mean_ms": float(np.nanmean(ms)) if timed else None,
                         "worst_ms": float(np.nanmax(ms)) if timed else None})
            if progress:
                print(f"  {name:8s} {traj.label:36s} {label:16s} FLIP {flips.mean():.4f} (worst {flips.max():.4f},"
                      f" floor {floor:.4f}), flicker {flick.mean():.4f}")
    finally:
        r.settings = base
    return rows


def run(out_dir: Path, size=(1440, 1600), scenes=("default", "sponza"), kinds=KINDS, rates=RATES_HZ,
        seconds: float = SECONDS, variants: dict | None = None, reference_spp: int = REFERENCE_SPP,
        pose_seed: int = POSE_SEED, backend=None, progress=True) -> dict:
    variants = variants or VARIANTS
    gl = create_context(backend)
    rows, skipped = [], {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            trajectories = draw_trajectories(scene, name, kinds, rates, seconds=seconds, seed=pose_seed)
            with Renderer(scene, bench_config(name), gl=gl) as r:
                for traj in trajectories:
                    rows += trajectory_rows(r, rig, name, traj, variants, reference_spp, progress)
        meta = {**device_meta(gl.info()), "bench": "motion", "per_eye_size": list(size), "kinds": list(kinds),
                "rates_hz": list(rates), "seconds": seconds, "reference_spp": reference_spp,
                "reference_seed": REFERENCE_SEED, "pose_seed": pose_seed, "skipped": skipped,
                "timings_meaningful": not gl.is_software,
                "configs": {"default": "rayvr/assets/default_room.toml", "other": "bench.rays.hybrid_config"}}
        result = {"meta": meta, "rows": rows}
        write_report(out_dir, "motion", result)
    finally:
        gl.release()
    return result
