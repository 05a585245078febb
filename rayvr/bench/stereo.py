"""`rayvr bench stereo`: the stereo modes (rayvr/frame/stereo.py) against each other on the same frame.

Per scene and mode (dual, warp with two and with one depth layer, reuse), the benchmark's effect config (the room's shipped config;
Sponza's hybrid frame of `rayvr bench rays`, floors on BVH reflections), both eyes:
  - GPU ms per pass and per frame (median over `repeat` frames after timing.settle warm-up), and
    the frame of the left eye alone (`mono_ms`, `left_ms`; `right_ms` = frame - mono); `second_eye_share` = (frame - mono) / mono, the
    cost of the second eye relative to one eye (dual ~1; the issues' targets: warp <= 0.35,
    reuse <= 0.40);
  - mean FLIP of each eye against `dual` with the same seed (what the mode changes: view-dependent
    shading copied across eyes, resampling, inpainted holes) and against `dual` with another seed
    (DESIGN: a reference and its variant never share a seed); `noise_floor` is dual against dual
    with the other seed, the sampling noise both numbers sit on;
  - warp: hole fraction per eye (disoccluded + off screen), the share of pixels found on the
    central view's second depth layer, and quadtree nodes per pixel;
    reuse: the share of right-eye pixels that took the left eye's shading.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..gl.context import create_context
from ..scene.materials import load_config
from ..renderer import Renderer
from ..scene.loader import ASSETS_DIR
from .rays import hybrid_config, time_frame
from .report import device_meta, write_report
from .scenes import bench_scenes

# (mode, warp depth layers), dual first: every other row is judged against it
VARIANTS = (("dual", 0), ("warp", 2), ("warp", 1), ("reuse", 0))
REFERENCE_SEED = 1  # dual with another seed: the reference that does not share the variants' seed 0


def bench_config(name: str):
    return load_config(ASSETS_DIR / "default_room.toml") if name == "default" else hybrid_config(name)


def mono_ms(renderer, rig, repeat: int) -> float:
    """Median GPU ms of a frame of the left eye alone."""
    renderer.warm_up(rig, "left", min_frames=2)
    totals = []
    for _ in range(repeat):
        fc = renderer.record(rig, "left", "color")
        totals.append(sum(renderer.read_ms(fc).values()))
    return float(np.median(totals))


def mode_rows(r: Renderer, rig, name: str, variants=VARIANTS, repeat: int = 20, progress=True,
              converged_spp: int = 0) -> list:
    """One row per (mode, warp layers) of `variants` (dual first: the others are judged against it)
    for the renderer `r` as configured: ms per pass and frame, each eye's ms (`left_ms`: the left
    eye alone; `right_ms`: what the second eye adds to it), FLIP of each eye against dual with the
    same seed and with REFERENCE_SEED, and what the mode did (holes, reused pixels). `rayvr bench
    gi` calls it for its Table 5. `converged_spp` > 0: also the right eye's FLIP against dual with
    both accumulated over that many samples (`flip_vs_dual_converged_right`: the error the mode
    makes, view-dependent shading and resampling, with the sampling noise mostly gone; its floor
    `noise_floor_converged_right` is dual against dual with the other seed at that count)."""
    from ..quality import metrics

    size = rig.size
    rows = []
    mono = mono_ms(r, rig, repeat)
    seed = r.settings.seed
    r.settings.seed = REFERENCE_SEED
    ref = r.render(rig)
    r.settings.seed = seed
    images, counts, converged = {}, {}, {}
    for mode, layers in variants:
        r.set_stereo(mode)
        r.settings.warp_layers = layers or 2
        names, med, total = time_frame(r, rig, repeat, warmup=3)
        images[mode, layers] = r.render(rig)
        counts[mode, layers] = r.stereo_counts()
        if converged_spp:
            converged[mode, layers] = r.render(rig, spp=converged_spp).right.color
        rows.append({"scene": name, "size": f"2x{size[0]}x{size[1]}", "mode": mode,
                     "warp_layers": layers or None, "frame_ms": total, "mono_ms": mono,
                     "left_ms": mono, "right_ms": total - mono,
                     "second_eye_share": (total - mono) / mono if mono > 0 else None,
                     "pass_ms": {k: med[k] for k in names if k in med}})
    r.set_stereo("dual")
    # the seed-to-seed noise of dual's right eye, that every row's FLIP sits on
    floor = metrics.flip(ref.right.color, images["dual", 0].right.color)
    if converged_spp:
        r.settings.seed = REFERENCE_SEED
        converged_floor = metrics.flip(r.render(rig, spp=converged_spp).right.color, converged["dual", 0])
        r.settings.seed = seed
    for row in rows:
        key = (row["mode"], row["warp_layers"] or 0)
        img = images[key]
        for eye in ("left", "right"):
            row[f"flip_vs_dual_{eye}"] = metrics.flip(images["dual", 0][eye].color, img[eye].color)
            row[f"flip_vs_dual_other_seed_{eye}"] = metrics.flip(ref[eye].color, img[eye].color)
        c = counts[key]
        if row["mode"] == "warp":
            for eye in ("left", "right"):
                row[f"hole_fraction_{eye}"] = c[f"hole_fraction_{eye}"]
                row[f"second_layer_fraction_{eye}"] = c[f"hits_second_layer_{eye}"] / c[f"pixels_{eye}"]
                row[f"nodes_per_pixel_{eye}"] = c[f"nodes_{eye}"] / c[f"pixels_{eye}"]
        if row["mode"] == "reuse":
            row["reused_fraction_right"] = c["reused"] / c["right_pixels"]
        row["noise_floor_right"] = floor
        if converged_spp:
            row["converged_spp"] = converged_spp
            row["flip_vs_dual_converged_right"] = metrics.flip(converged["dual", 0], converged[key])
            row["noise_floor_converged_right"] = converged_floor
        if progress:
            print(f"  {name:8s} {row['mode']:6s}{row['warp_layers'] or '':1} frame {row['frame_ms']:.3f} ms (mono {mono:.3f}), "
                  f"second eye {row['second_eye_share'] or 0:.2f} of one, FLIP vs dual right "
                  f"{row['flip_vs_dual_right']:.4f}")
    return rows


def run(out_dir: Path, size=(1440, 1600), scenes=("default", "sponza"), repeat=20, backend=None,
        progress=True) -> dict:
    gl = create_context(backend)
    rows, skipped = [], {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            with Renderer(scene, bench_config(name), gl=gl) as r:
                rows += mode_rows(r, rig, name, VARIANTS, repeat, progress)
        meta = {**device_meta(gl.info()), "bench": "stereo", "per_eye_size": list(size), "repeat": repeat,
                "skipped": skipped, "timings_meaningful": not gl.is_software,
                "configs": {"default": "rayvr/assets/default_room.toml", "other": "bench.rays.hybrid_config"}}
        result = {"meta": meta, "rows": rows}
        write_report(out_dir, "stereo", result)
    finally:
        gl.release()
    return result
