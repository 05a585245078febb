"""`rayvr bench ssrt`: screen-space ray tracing through the quadtree (Widmer et al. 2015,
rayvr/passes/quadtree.py) against the perspective-correct DDA baseline (McGuire & Mara 2014,
rayvr/accel/dda.py), on the mirror rays of every G-buffer pixel of one eye.

Reports per scene: quadtree build ms per layer (lossless and with merge thresholds), rays/s and
node visits (mean, p99) of the quadtree trace, the same rays through the DDA at two settings
(steps per ray, share reaching max_steps), the Hi-Z min-max pyramid (rayvr/accel/hiz.py: build
ms per layer, rays/s, cells visited, share reaching max_iterations), and how often the baselines
agree with the lossless quadtree on the outcome. First measurements only: the error against BVH
reflections, `warp` and the gamma sweeps arrive with the `ssr` effect (issue 10).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..accel.dda import DdaTracer
from ..accel.hiz import HizTracer
from ..context import create_context
from ..passes.quadtree import QuadtreeTracer
from ..renderer import Renderer
from .report import device_meta, write_report
from .scenes import bench_scenes

# (gamma_norm as the cosine of the largest normal angle, gamma_dist in z units): lossless first
GAMMAS = ((1.0, 0.0), (math.cos(math.radians(10.0)), 1e-3))
DDA_SETTINGS = ((256, 1.0), (64, 4.0))  # (max_steps, stride)
HIZ_SETTINGS = ((256, 2), (1024, 2))    # (max_iterations, start_level); mirror rays skip their origin's pixel


def mirror_rays(frame, eye, origin):
    """Scene-local (origins, directions) of the mirror rays of every covered pixel of `eye`,
    started a hair off the surface along the normal."""
    img = frame[eye.name]
    hit = img.depth > 0
    p = img.aux["position"][hit] - origin
    n = img.aux["normal"][hit].astype(np.float64)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    v = p - (eye.position - origin)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    d = v - 2.0 * (v * n).sum(1, keepdims=True) * n
    o = p + n * (1e-4 * img.depth[hit])[:, None]
    return o.astype(np.float32), d.astype(np.float32)


def effect_frames(gl, scene, rig, name: str, repeat: int) -> list[dict]:
    """The hybrid frame of `rayvr bench rays` (shadows everywhere, mirrors on MIRRORS) with the
    mirrors on BVH `reflections` and on `ssr`: GPU ms per pass and mean FLIP of the ssr image
    against the reflections one over the mirror pixels (both eyes)."""
    from ..effects import EFFECTS
    from ..materials import parse_config
    from . import metrics
    from .rays import MIRRORS, time_frame

    out, images = [], {}
    for effect in ("reflections", "ssr"):
        cfg = parse_config({"default": "shadows", "materials": {m: effect for m in MIRRORS.get(name, ())}},
                           f"bench:{name}:{effect}")
        with Renderer(scene, cfg, gl=gl) as r:
            names, med, total = time_frame(r, rig, repeat, warmup=3)
            frame = r.render(rig, aux=("effect",))
        images[effect] = (np.concatenate([frame.left.color, frame.right.color], axis=1),
                          np.concatenate([frame.left.aux["effect"], frame.right.aux["effect"]], axis=1))
        mirror_ms = med.get("rt_" + effect, 0.0) + med.get("quadtree", 0.0)
        out.append({"scene": name, "tracer": f"frame:{effect}", "mirrors": list(MIRRORS.get(name, ())),
                    "frame_ms": total, "mirror_ms": mirror_ms, "pass_ms": {k: med[k] for k in names if k in med}})
    ref, ids = images["reflections"]
    mask = ids == EFFECTS["reflections"].id
    out[1]["flip_vs_reflections_on_mirrors"] = metrics.flip(ref, images["ssr"][0], mask=mask)
    out[1]["mirror_pixel_share"] = float(mask.mean())
    return out


def run(out_dir: Path, size=(1440, 1600), scenes=("default", "sponza"), repeat=10, backend=None,
        progress=True) -> dict:
    gl = create_context(backend)
    rows, skipped = [], {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            with Renderer(scene, gl=gl) as r:
                frame = r.render(rig, aux=("position", "normal"))
                eye = rig.eye("left")
                o, d = mirror_rays(frame, eye, scene.origin)
                qt, dda = QuadtreeTracer(r), DdaTracer(gl)
                try:
                    for gn, gd in GAMMAS:
                        t = qt.time(rig, o, d, eye=0, gamma_norm=gn, gamma_dist=gd, repeats=repeat)
                        status, nodes, _, _ = qt.trace(o, d, eye=0)  # through the tree just timed
                        row = {"scene": name, "size": f"2x{size[0]}x{size[1]}", "rays": len(o), "tracer": "quadtree",
                               "gamma_norm": gn, "gamma_dist": gd, "build_ms_per_layer": t["build"]["ms"] / 2,
                               "gpu_ms": t["trace"]["ms"], "gpu_ms_min": t["trace"]["gpu_ms_min"],
                               "gpu_ms_max": t["trace"]["gpu_ms_max"], "grays_s": t["rays_per_s"] / 1e9,
                               "nodes_mean": float(nodes.mean()), "nodes_p99": float(np.percentile(nodes, 99)),
                               "hit_share": float((status == 1).mean())}
                        rows.append(row)
                        if gn == 1.0:
                            lossless = status
                        if progress:
                            print(f"  {name:8s} quadtree g=({gn:.4f},{gd:g}) build {row['build_ms_per_layer']:.3f} "
                                  f"ms/layer, {row['grays_s']:.2f} GRays/s, nodes {row['nodes_mean']:.1f} mean")
                    gb = r.resource("gbuffer")
                    for steps, stride in DDA_SETTINGS:
                        t = dda.time_trace(gb, rig.eyes(), scene.origin, o, d, eye=0, max_steps=steps, stride=stride,
                                           repeats=repeat)
                        res = dda.trace(gb, rig.eyes(), scene.origin, o, d, eye=0, max_steps=steps, stride=stride)
                        row = {"scene": name, "size": f"2x{size[0]}x{size[1]}", "rays": len(o), "tracer": "dda",
                               "max_steps": steps, "stride": stride, "gpu_ms": t["gpu_ms"],
                               "grays_s": t["rays_per_s"] / 1e9, "steps_mean": t["mean_steps"],
                               "max_steps_reached": t["max_steps_reached"],
                               "hit_share": float((res.status == 1).mean()),
                               "status_agrees_with_quadtree": float((res.status == lossless).mean())}
                        rows.append(row)
                        if progress:
                            print(f"  {name:8s} dda steps {steps} stride {stride:g}: {row['grays_s']:.2f} GRays/s, "
                                  f"{row['steps_mean']:.1f} steps, agrees with quadtree "
                                  f"{row['status_agrees_with_quadtree']:.1%}")
                    hiz = HizTracer(r)
                    try:
                        for iters, start in HIZ_SETTINGS:
                            t = hiz.time(rig, o, d, eye=0, start_level=start, max_iterations=iters, skip_origin=True,
                                         repeats=repeat)
                            res = hiz.trace(o, d, eye=0, start_level=start, max_iterations=iters, skip_origin=True)
                            row = {"scene": name, "size": f"2x{size[0]}x{size[1]}", "rays": len(o), "tracer": "hiz",
                                   "max_iterations": iters, "start_level": start,
                                   "build_ms_per_layer": t["build"]["ms"] / 2, "gpu_ms": t["trace"]["ms"],
                                   "gpu_ms_min": t["trace"]["gpu_ms_min"], "gpu_ms_max": t["trace"]["gpu_ms_max"],
                                   "grays_s": t["rays_per_s"] / 1e9, "iterations_mean": t["mean_iterations"],
                                   "iterations_p99": float(np.percentile(res.iterations, 99)),
                                   "max_iterations_reached": t["max_iterations_reached"],
                                   "hit_share": float((res.status == 1).mean()),
                                   "status_agrees_with_quadtree": float((res.status == lossless).mean())}
                            rows.append(row)
                            if progress:
                                print(f"  {name:8s} hiz iterations {iters}: build {row['build_ms_per_layer']:.3f} "
                                      f"ms/layer, {row['grays_s']:.2f} GRays/s, {row['iterations_mean']:.1f} "
                                      f"iterations, agrees with quadtree {row['status_agrees_with_quadtree']:.1%}")
                    finally:
                        hiz.release()
                finally:
                    qt.release()
                    dda.release()
            for row in effect_frames(gl, scene, rig, name, repeat):
                rows.append(row)
                if progress:
                    flip = row.get("flip_vs_reflections_on_mirrors")
                    print(f"  {name:8s} {row['tracer']:18s} frame {row['frame_ms']:.3f} ms, mirrors {row['mirror_ms']:.3f} ms"
                          + (f", mean FLIP vs reflections on the mirrors {flip:.4f}" if flip is not None else ""))
        meta = {**device_meta(gl.info()), "bench": "ssrt", "per_eye_size": list(size), "repeat": repeat,
                "skipped": skipped, "rays": "mirror rays of every covered pixel of the left eye",
                "what_times_include": "GL timer queries around the dispatches after times settle; rays and "
                                      "the G-buffer already on the GPU"}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "ssrt", result)
    return result
