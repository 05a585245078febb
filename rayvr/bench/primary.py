"""`rayvr bench primary`: ray-cast primary visibility per camera model and sub-ray count, against
the raster G-buffer of the same view (the physical reference).

Per scene (the benchmark views of rayvr/bench/scenes.py, both eyes of the stereo rig) and per row
of CONFIGS x sub-ray counts: the frame (all-`raster` materials, so shading is one cheap pass and
the figures are about visibility) is rendered through the Renderer's frame graph; GPU ms per pass
are medians over `repeat` frames after a warm-up that lasts until frame times settle
(rays.time_frame), and `primary_ms` is the primary-ray kernels alone (the MSAA `trace` kernel, or
the `cast` kernel summed over the rounds), from frames timed kernel by kernel. `sub_rays` counts
the camera rays a frame casts (samples x sub-rays x colour channel sets); `sub_grays_s` is
sub_rays / primary_ms. MSAA frames shade once per pixel per distinct triangle: `rounds` is how many
shading rounds the frame needed (the most distinct triangles any pixel saw, per channel set).
"""
from __future__ import annotations

import numpy as np

from ..camera import StereoRig
from ..cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from ..cameras.sampling import SAMPLE_COUNTS
from ..context import create_context
from ..renderer import Renderer, RenderSettings
from .rays import time_frame
from .report import device_meta, write_report
from .scenes import bench_scenes

# name -> (camera model, fov_y or None for the view's, primary visibility); the paper's Table 5
# rows where rayvr has them: pinhole (rays, and the raster reference), pre-distorted (one set and
# chromatic), foveated, wide 210x130, thin lens at three focus distances.
CONFIGS = {
    "raster_gbuffer": (Pinhole(), None, "raster"),
    "pinhole": (Pinhole(), None, "rays"),
    "distorted": (Distorted(coefficients=(0.22, 0.24, 0.0)), None, "rays"),
    "distorted_chromatic": (Distorted(), None, "rays"),
    "foveated": (Foveated(), None, "rays"),
    "wide_210x130": (Wide(fov_x=210.0), 130.0, "rays"),
    "dof_near": (ThinLens(aperture=0.02, focus=1.0), None, "rays"),
    "dof_mid": (ThinLens(aperture=0.02, focus=4.0), None, "rays"),
    "dof_far": (ThinLens(aperture=0.02, focus=16.0), None, "rays"),
}


def samples_per_frame(rig: StereoRig) -> int:
    """Camera samples of both eyes (a foveated pattern has fewer than pixels)."""
    return int(sum((rig.camera.footprint(e) > 0).sum() for e in rig.eyes()))


def primary_kernel_ms(renderer, rig, repeat=5) -> tuple[float, int]:
    """Median GPU ms of the primary-ray kernels (not the MSAA select) and the frame's rounds."""
    ms, rounds = [], 1
    for _ in range(repeat):
        fc = renderer.record(rig, "both", "color", profile=True)
        t = renderer.read_ms(fc)
        ms.append(sum(v for k, v in t.items() if k in ("primary_rays.trace", "primary_rays.cast")))
        rounds = fc.round.index + 1
    return float(np.median(ms)), rounds


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=20, warmup=3, counts=SAMPLE_COUNTS,
        ssaa=(4,), configs=tuple(CONFIGS), custom=None, backend=None, progress=True) -> dict:
    """`custom` = (camera model, fov_y or None): that camera instead of CONFIGS' (beside the raster
    reference), as `rayvr bench primary --camera-model ... --camera-param ...` asks."""
    table = dict(CONFIGS)
    if custom is not None:
        table["custom"] = (custom[0], custom[1], "rays")
        configs = ("raster_gbuffer", "custom")
    gl = create_context(backend)
    rows, skipped = [], {}
    try:
        for name, scene, view in bench_scenes(scenes, size, skipped):
            for cname in configs:
                model, fov, primary = table[cname]
                rig = StereoRig(view.pose, ipd=view.ipd, fov_y=fov or view.fov_y, near=view.near, size=view.size,
                                camera=model)
                samples = samples_per_frame(rig)
                runs = [(1, False)] if primary == "raster" else \
                    [(n, False) for n in counts] + [(n, True) for n in ssaa if n > 1]
                for n, shade_all in runs:
                    settings = RenderSettings(primary=primary, msaa=n, ssaa=shade_all)
                    with Renderer(scene, gl=gl, settings=settings) as r:
                        names, med, total = time_frame(r, rig, repeat, warmup)
                        row = {"scene": name, "config": cname, "camera": model.name, "primary": primary,
                               "sub_rays_per_sample": n, "shading": "ssaa" if shade_all else "msaa",
                               "size": f"2x{size[0]}x{size[1]}", "total_ms": total,
                               "pass_ms": {k: med[k] for k in names if k in med}}
                        if primary == "rays":
                            kernel, rounds = primary_kernel_ms(r, rig)
                            sub_rays = samples * n * model.channels
                            row.update(samples=samples, channels=model.channels, sub_rays=sub_rays,
                                       primary_ms=kernel, rounds=rounds,
                                       sub_grays_s=sub_rays / (kernel * 1e6) if kernel > 0 else None)
                        else:
                            row["visibility_ms"] = med.get("visibility", 0.0) + med.get("gbuffer", 0.0)
                    rows.append(row)
                    if progress:
                        rate = f", {row['sub_grays_s']:.3f} G sub-rays/s" if row.get("sub_grays_s") else ""
                        print(f"  {name:8s} {cname:20s} {n:2d}x {row['shading']} frame {total:.3f} ms{rate}")
        meta = {**device_meta(gl.info()), "bench": "primary", "per_eye_size": list(size), "repeat": repeat,
                "skipped": skipped, "materials": "all raster (visibility, not shading, is measured)",
                "what_times_include": {
                    "pass_ms": "GL timer query per pass, summed over a sampled frame's rounds; medians",
                    "primary_ms": "the primary-ray kernels alone (MSAA trace / per-round cast), kernel "
                                  "by kernel; BVH already on the GPU",
                    "msaa_note": "an MSAA frame reads back one number (its rounds) after the trace: a "
                                 "GPU sync the frame total includes"}}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "primary", result)
    return result
