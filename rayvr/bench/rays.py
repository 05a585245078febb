"""`rayvr bench rays`: BVH build, GPU rays/s against Embree on the same rays, and a full stereo
hybrid frame with per-pass GPU ms.

Per scene (the benchmark views of rayvr/bench/scenes.py, both eyes of the stereo rig):
  build     binned-SAH build time (numpy, host), SAH cost, nodes, depth
  primary   the rig's camera rays (coherent), closest hit
  shadow    from each primary hit (barycentric point, offset_ray) to the scene's first point or
            rect light (or along its directional light), any hit
  reflect   mirror reflection of each primary ray at its hit (geometric normal), closest hit:
            incoherent secondary rays
GPU rays/s come from GL timer queries around `repeat` dispatches of rayvr/glsl/accel/trace_rays.comp
with the rays already on the GPU. Embree (embreex, one scene per process, a fork pool over every host
core) traces the same float32 rays; its time is the wall time of the pool's map after a warm-up.
Agreement with Embree (same triangle / same occlusion) is reported beside the speeds.

The hybrid frame renders the scene with `shadows` on every material and mirror `reflections` on
the reflective ones (MIRRORS), through the Renderer's frame graph: raster G-buffer, classify,
per-effect passes by indirect dispatch, tonemap. Per-pass GPU ms are medians over `repeat` frames
after a warm-up; `effect_kernel_ms` splits the effect passes into their wavefront kernels (shading
vs tracing, medians of 5 more frames timed kernel by kernel).
Sponza (no MTL) is split into its OBJ groups by the loader; its mirror config is the `floors`
group, about 28 % of the pixels of the benchmark view.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import time

import numpy as np

from ..accel.bvh import offset_ray
from ..accel.gpu import MISS, GpuBvh, RayTracer
from ..accel.scene import build_scene_bvh
from ..context import create_context
from ..materials import parse_config
from ..renderer import Renderer, RenderSettings
from .report import device_meta, write_report
from .scenes import bench_scenes

# Reflective materials of each benchmark scene: mirror reflections in the hybrid frame.
MIRRORS = {"default": ("mirror*", "gold"), "sponza": ("floors",)}


def hybrid_config(name: str):
    return parse_config({"default": "shadows",
                         "materials": {m: {"effect": "reflections", "bounces": 1} for m in MIRRORS.get(name, ())}},
                        f"bench:{name}")


def primary_rays(rig, origin):
    o, d = [], []
    for eye in rig.eyes():
        dirs = eye.ray_directions()[::-1].reshape(-1, 3)  # GL rows (bottom-up), as the passes trace
        d.append(dirs)
        o.append(np.broadcast_to(eye.position - origin, dirs.shape))
    return np.concatenate(o).astype(np.float32), np.concatenate(d).astype(np.float32)


def secondary_rays(scene, bvh, o, d, hits):
    """Shadow rays to the first light and mirror-reflected rays, from the primary hits."""
    h = np.flatnonzero(hits.prim != MISS)
    tri = scene.vertices[scene.indices[hits.prim[h]]].astype(np.float32)
    p = tri[:, 0] + hits.u[h, None] * (tri[:, 1] - tri[:, 0]) + hits.v[h, None] * (tri[:, 2] - tri[:, 0])
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    n *= -np.sign((n * d[h]).sum(1, keepdims=True))  # facing the eye
    n = n.astype(np.float32)
    light = next((l for l in scene.lights if l.kind in ("point", "rect")), None)
    if light is not None:
        target = (np.asarray(light.position) - scene.origin).astype(np.float32)
        sd = target - p
        side = np.where((sd * n).sum(1, keepdims=True) >= 0, n, -n)
        so = offset_ray(p, side)
        sd, stmax = (target - so).astype(np.float32), np.float32(1.0 - 1e-4)
    else:
        l = -np.asarray(scene.lights[0].direction if scene.lights else (0, -1, 0), np.float32)
        so = offset_ray(p, np.where((n @ l)[:, None] >= 0, n, -n))
        sd, stmax = np.broadcast_to(l, p.shape).astype(np.float32), np.float32(3e38)
    rd = d[h] - 2 * (d[h] * n).sum(1, keepdims=True) * n
    return {"shadow": (so, sd, stmax, "any"), "reflect": (offset_ray(p, n), rd.astype(np.float32), np.float32(3e38), "closest")}


# -------------------------------------------------------------------------- Embree, all cores

_WORK: dict = {}


def _embree_init():
    from embreex import mesh_construction, rtcore_scene
    s = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(s, _WORK["vertices"], _WORK["indices"])
    _WORK["scene"] = s


def _embree_chunk(job):
    """Trace rays [lo, hi) of a kind already in this worker; returns the hits and the seconds the
    trace call itself took (no pool dispatch, no transfer of the results)."""
    kind, lo, hi = job
    o, d, tmax, mode = _WORK["rays"][kind]
    dists = np.full(hi - lo, tmax, np.float32)
    t0 = time.perf_counter()
    if mode == "any":
        hits = _WORK["scene"].run(o[lo:hi], d[lo:hi], dists=dists, query="OCCLUDED") != -1
    else:
        hits = _WORK["scene"].run(o[lo:hi], d[lo:hi], dists=dists)
    return lo, hits, time.perf_counter() - t0


def embree_trace(pool, workers, kind, n, repeat=1):
    """(hits, wall seconds, trace seconds): wall is the whole parallel map, results back in this
    process included (the rays are in the workers before timing); trace is the busiest worker's
    time inside Embree's calls (embreex traces ray by ray: rtcIntersect1, no packets/streams)."""
    chunk = max(1, -(-n // (workers * 8)))
    jobs = [(kind, s, min(n, s + chunk)) for s in range(0, n, chunk)]
    best, best_trace = np.inf, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        parts = pool.map(_embree_chunk, jobs)
        best = min(best, time.perf_counter() - t0)
        # Chunks are handed out in order to `workers` processes: the ideal spread of the tracing.
        best_trace = min(best_trace, sum(p[2] for p in parts) / workers)
    out = np.concatenate([r for _, r, _ in sorted(parts, key=lambda x: x[0])])
    return out, best, best_trace


# -------------------------------------------------------------------------- the run

def time_frame(renderer, rig, repeat, warmup, warmup_s=0.3):
    """Median GPU ms per pass and of the frame total over `repeat` frames, after a warm-up of at
    least `warmup` frames and `warmup_s` seconds that lasts until frame times settle."""
    names, ms = None, {}
    renderer.warm_up(rig, seconds=warmup_s, min_frames=warmup)
    for i in range(repeat):
        fc = renderer.record(rig, "both", "color")
        renderer.gl.ctx.finish()
        t = renderer.read_ms(fc)
        names = fc.pass_names
        for k, v in t.items():
            ms.setdefault(k, []).append(v)
    med = {k: float(np.median(v)) for k, v in ms.items()}
    totals = np.sum([ms[k] for k in ms], axis=0)
    return names, med, float(np.median(totals))


def time_effect_stages(renderer, rig, repeat=5) -> dict:
    """Median GPU ms of each kernel of the wavefront effect passes ("rt_shadows.shadow", ...)."""
    ms: dict = {}
    for _ in range(repeat):
        fc = renderer.record(rig, "both", "color", profile=True)
        for name, v in renderer.read_ms(fc).items():
            if name.startswith("rt_") and "." in name:
                ms.setdefault(name, []).append(v)
    return {k: float(np.median(v)) for k, v in ms.items()}


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=20, warmup=3, workers=None,
        backend=None, progress=True) -> dict:
    workers = workers or os.cpu_count() or 1
    gl = create_context(backend)
    rows, frames, skipped = [], [], {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            bvh = build_scene_bvh(scene)
            gpu = GpuBvh(gl, bvh)
            rt = RayTracer(gl, gpu)
            o, d = primary_rays(rig, scene.origin)
            hits = rt.trace(o, d)
            rays = {"primary": (o, d, np.float32(3e38), "closest"), **secondary_rays(scene, bvh, o, d, hits)}
            base = {"scene": name, "triangles": scene.triangle_count, "build_s": bvh.build_seconds,
                    "sah_cost": bvh.sah_cost(), "gpu_nodes": bvh.gpu_node_count, "max_depth": bvh.max_depth}
            _WORK.update(vertices=np.ascontiguousarray(scene.vertices, np.float32),
                         indices=np.ascontiguousarray(scene.indices, np.int32), rays=rays)
            try:
                import embreex  # noqa: F401
                pool = mp.get_context("fork").Pool(workers, initializer=_embree_init)
                pool.map(_embree_chunk, [("primary", 0, 1)] * workers)  # every worker built its scene
            except ImportError:
                pool = None
            try:
                for kind, (ro, rd, tmax, mode) in rays.items():
                    g = rt.time_trace(ro, rd, tmax=tmax, mode=mode, repeats=repeat)
                    row = {**base, "rays_kind": kind, "rays": len(ro), "gpu_ms": g["gpu_ms"],
                           "gpu_ms_min": g["gpu_ms_min"], "gpu_ms_max": g["gpu_ms_max"],
                           "gpu_grays_s": g["rays_per_s"] / 1e9}
                    if pool is not None:
                        ref, secs, trace_secs = embree_trace(pool, workers, kind, len(ro), repeat=3)
                        mine = rt.trace(ro, rd, tmax=tmax, mode=mode)
                        if mode == "any":
                            agree = float((mine == ref).mean())
                        else:
                            agree = float((mine.prim == np.where(ref >= 0, ref, -1).astype(np.uint32)).mean())
                        row.update(embree_ms=secs * 1e3, embree_grays_s=len(ro) / secs / 1e9,
                                   speedup_vs_embree=(len(ro) / secs) and g["rays_per_s"] / (len(ro) / secs),
                                   embree_trace_ms=trace_secs * 1e3,
                                   speedup_vs_embree_trace=g["rays_per_s"] * trace_secs / len(ro),
                                   agree_with_embree=agree)
                    rows.append(row)
                    if progress:
                        print(f"  {name:8s} {kind:8s} {row['gpu_grays_s']:.3f} GRays/s GPU"
                              + (f", Embree {row['embree_grays_s']:.3f} ({row['speedup_vs_embree']:.1f}x; "
                                 f"{row['speedup_vs_embree_trace']:.1f}x its trace calls alone),"
                                 f" agree {row['agree_with_embree']:.4%}" if pool else ""))
            finally:
                if pool is not None:
                    pool.close()
                    pool.join()
                _WORK.clear()
                gpu.release()
            r = Renderer(scene, hybrid_config(name), gl=gl, settings=RenderSettings())
            try:
                names, med, total = time_frame(r, rig, repeat, warmup)
                stages = time_effect_stages(r, rig)
                counts = r.pixel_counts()
                pixels = 2 * size[0] * size[1]
                frames.append({"scene": name, "size": f"2x{size[0]}x{size[1]}", "passes": names,
                               "pass_ms": {k: med[k] for k in names if k in med}, "total_ms": total,
                               "mirror_pixel_fraction": counts["reflections"] / pixels,
                               "shadow_pixel_fraction": counts["shadows"] / pixels,
                               "effect_kernel_ms": stages,
                               "config": {"default": "shadows", "reflections": list(MIRRORS.get(name, ()))}})
                if progress:
                    print(f"  {name:8s} hybrid frame {total:.3f} ms: "
                          + ", ".join(f"{k} {v:.3f}" for k, v in frames[-1]["pass_ms"].items()))
                    print(f"  {name:8s} effect kernels: " + ", ".join(f"{k} {v:.3f}" for k, v in stages.items()))
            finally:
                r.release()
        meta = {**device_meta(gl.info()), "bench": "rays", "per_eye_size": list(size), "repeat": repeat,
                "host_cores": os.cpu_count(), "embree_workers": workers, "skipped": skipped,
                "what_times_include": {
                    "gpu_ms": "GL timer query around the trace dispatches only; rays and BVH already "
                              "on the GPU, no upload or readback",
                    "embree_ms": "wall time of the parallel map over all host cores (embreex, one "
                                 "rtcIntersect1 per ray); rays already in the workers, hits sent back",
                    "embree_trace_ms": "time inside Embree's trace calls, summed over chunks and "
                                       "divided by the workers (perfect spread, no dispatch, no transfer)"},
                "hybrid_frames": frames}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "rays", result)
    return result
