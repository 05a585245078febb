"""`rayvr bench primary`: ray-cast primary visibility per camera model and sub-ray count, against
the raster G-buffer of the same view (the physical reference).

Two suites, per scene (the benchmark views of rayvr/bench/scenes.py, both eyes of the stereo rig):
- `table5`: the HVVR paper's Table 5 rows at its 2160x1200 (two 1080x1200 eyes): normal 8/16/32x,
  pre-distorted 32x, post-distorted chromatic 16x and 32x, foveated 32x, wide 210x130 32x, thin-lens
  DoF (3 mm lens) focused at 0.5, 0.25 and 0.1 m, 16x; beside the raster G-buffer and 1x pinhole rays.
- `views`: the bench views at `size` per eye (2x1440x1600): CONFIGS x sub-ray counts (MSAA) and
  SSAA 4x; `--configs/--counts` (or a `custom` camera) measure a subset of these alone.

Per row, the frame (all-`raster` materials, so shading is one cheap pass and the figures are about
visibility) is rendered through one Renderer per scene (the BVH built once); GPU ms per pass are
medians over `repeat` frames after a warm-up that lasts until frame times settle (rays.time_frame),
and `primary_ms` is the primary-ray kernels alone (the MSAA `trace` kernel, or the `cast` kernel
summed over the rounds), from frames timed kernel by kernel. `sub_rays` counts the camera rays a
frame casts (samples x sub-rays x colour channel sets); `sub_grays_s` is sub_rays / primary_ms.
MSAA frames shade once per pixel per distinct triangle: `rounds` is how many shading rounds the
frame needed (the most distinct triangles any pixel saw, per channel set, summed over the sets);
the CPU records rounds without waiting for that count (frame/passes/primary_rays.py), so a frame may
record more, up to 8 per set, the extra ones skipping every pixel: `rounds_recorded` is the median
a plain frame recorded (and `rounds_recorded_max`). `visibility_ms` is what
makes the G-buffer: `visibility` + `gbuffer` passes (raster), `primary_rays` + `gbuffer` summed over
the rounds (rays).

Tile frustum culling in the frame (rows carry `tile_culling`, whether the frame culled; by default
each rays row as the renderer chooses (its frame plan's tile_culling), with `--tile-culling` once
without and once with it, with `--no-tile-culling` without): `primary_rays` first culls per 16x8-pixel
tile (its `cull` kernel, `cull_ms`, part of `primary_ms`) and traces each sub-ray from its tile's
entry list on the binary BVH. The same hits (tests); compare `total_ms`, `visibility_ms` and
`primary_ms` of a row with and without. Besides, each camera's central rays (one per sample, tile
order) are traced on their own by accel/gpu.py RayTracer, without and with culling
(`trace_grays_s`, `trace_tiles_grays_s`, `cull_ms` of that standalone dispatch: `trace_cull_ms`),
and their traversal work per ray is counted on the GPU (tile_work: per ray, tiles in tree order,
tiles front to back).

The JSON and markdown are rewritten (atomically) after every row: a run cut short keeps its rows.
The markdown's meta lists the issue's targets, each met or missed on the rows measured.
"""
from __future__ import annotations

import numpy as np

from ..accel.gpu import RayTracer
from ..frame.cameras.rig import StereoRig
from ..frame.cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from ..gl.context import create_context
from ..renderer import Renderer, RenderSettings
from .rays import primary_rays, time_frame
from .report import device_meta, write_report
from .scenes import bench_scenes

# name -> (camera model, fov_y or None for the view's, primary visibility)
CONFIGS = {
    "raster_gbuffer": (Pinhole(), None, "raster"),
    "pinhole": (Pinhole(), None, "rays"),
    "distorted": (Distorted(coefficients=(0.22, 0.24, 0.0)), None, "rays"),  # pre-distorted: one grid
    "distorted_chromatic": (Distorted(), None, "rays"),  # post-distorted chromatic: a grid per channel set
    "foveated": (Foveated(), None, "rays"),
    "wide_210x130": (Wide(fov_x=210.0), 130.0, "rays"),
    "dof_0.5m": (ThinLens(aperture=0.0015, focus=0.5), None, "rays"),  # the paper's 3 mm lens
    "dof_0.25m": (ThinLens(aperture=0.0015, focus=0.25), None, "rays"),
    "dof_0.1m": (ThinLens(aperture=0.0015, focus=0.1), None, "rays"),
}
VIEW_CONFIGS = ("raster_gbuffer", "pinhole")  # the views suite's default rows
VIEW_COUNTS = (1, 4, 16)
TABLE5_SIZE = (1080, 1200)  # per eye: the paper's 2160 x 1200
# (config, sub-rays per sample), in the paper's order
TABLE5 = (("raster_gbuffer", 1), ("pinhole", 1), ("pinhole", 8), ("pinhole", 16), ("pinhole", 32),
          ("distorted", 32), ("distorted_chromatic", 16), ("distorted_chromatic", 32), ("foveated", 32),
          ("wide_210x130", 32), ("dof_0.5m", 16), ("dof_0.25m", 16), ("dof_0.1m", 16))
SUITES = ("table5", "views")


def samples_per_frame(rig: StereoRig) -> int:
    """Camera samples of both eyes (a foveated pattern has fewer than pixels)."""
    return int(sum((rig.camera.footprint(e) > 0).sum() for e in rig.eyes()))


def primary_kernel_ms(renderer, rig, repeat=5) -> tuple[float, float]:
    """Median GPU ms of the primary-ray kernels (the tile cull with the trace or casts, not the MSAA
    select), and of the tile cull alone (0 without culling)."""
    ms, cull = [], []
    for _ in range(repeat):
        fc = renderer.record(rig, "both", "color", profile=True)
        t = renderer.read_ms(fc)
        ms.append(sum(v for k, v in t.items() if k in ("primary_rays.trace", "primary_rays.cast", "primary_rays.cull")))
        cull.append(t.get("primary_rays.cull", 0.0))
    return float(np.median(ms)), float(np.median(cull))


def frame_rounds(renderer, rig, repeat=5) -> dict:
    """Rounds a plain frame needed and recorded (median and most over `repeat` frames)."""
    recorded, needed = [], 1
    for _ in range(repeat):
        fc = renderer.record(rig, "both", "color")
        renderer.gl.ctx.finish()
        recorded.append(fc.round.index + 1)
        needed = sum(c.needed() for c in fc.channel_rounds) or 1
    return {"rounds": needed, "rounds_recorded": float(np.median(recorded)), "rounds_recorded_max": max(recorded)}


def tile_work(gl, gpu_bvh, o, d) -> dict:
    """Mean traversal work per ray of the rays (GPU-counted, bvh.glsl BVH_COUNT_WORK: the same on
    every device) traced per ray (`trace_`), from tile entry lists in tree order (`tree_`) and front
    to back (`tiles_`, the default): node fetches, entry box tests, triangle tests; and whether all
    three agree exactly on every ray's triangle."""
    out, prims = {}, []
    for name, tiles, order in (("trace", False, True), ("tree", True, False), ("tiles", True, True)):
        work = {}
        prims.append(RayTracer(gl.ctx, gpu_bvh, tile_sort=order).trace(o, d, tiles=tiles, work=work).prim)
        out.update({f"{name}_{k}": float(v.mean()) for k, v in work.items() if tiles or k != "entry_tests"})
    out["tiles_agree"] = float(((prims[0] == prims[1]) & (prims[0] == prims[2])).mean())
    return out


def tile_culling(gl, gpu_bvh, rig, origin, repeat) -> dict:
    """The camera's central rays traced standalone (binary BVH) without and with tile culling, and
    their traversal work (tile_work)."""
    o, d = primary_rays(rig, origin, tiled=True)
    rt = RayTracer(gl.ctx, gpu_bvh)
    plain = rt.time_trace(o, d, repeats=repeat)
    culled = rt.time_trace(o, d, repeats=repeat, tiles=True)
    return {"trace_rays": len(o), "trace_grays_s": plain["rays_per_s"] / 1e9,
            "trace_tiles_grays_s": culled["rays_per_s"] / 1e9, "trace_cull_ms": culled["cull_ms"],
            **tile_work(gl, gpu_bvh, o, d)}


def targets(rows) -> dict:
    """The issue's targets for this bench, each 'met'/'missed' with the figures, on the rows measured
    (per BVH build and per tile culling, named in the key when the rows have several; the raster
    reference rows count in each)."""
    builds = list(dict.fromkeys(r.get("bvh_build", "sah") for r in rows))
    culling = list(dict.fromkeys(r.get("tile_culling", False) for r in rows if r.get("primary") != "raster")) or [False]
    out = {}
    for b in builds:
        for tc in culling:
            label = " ".join(([b] if len(builds) > 1 else []) + (["tile culling" if tc else "per ray"]
                                                                 if len(culling) > 1 else []))
            group = [r for r in rows if r.get("bvh_build", "sah") == b
                     and (r.get("primary") == "raster" or r.get("tile_culling", False) == tc)]
            out.update({(f"[{label}] " if label else "") + k: v for k, v in build_targets(group).items()})
    return out


def build_targets(rows) -> dict:
    out = {}

    def verdict(ok, text):
        return ("met: " if ok else "MISSED: ") + text

    views = [r for r in rows if r["suite"] == "views"]
    one = [r for r in views if r["config"] == "pinhole" and r["sub_rays_per_sample"] == 1 and r.get("sub_grays_s")]
    if one:
        worst = min(one, key=lambda r: r["sub_grays_s"])
        out["coherent primary rays >= 4 GRays/s on every bench view (1x pinhole cast)"] = verdict(
            worst["sub_grays_s"] >= 4.0, ", ".join(f"{r['scene']} {r['sub_grays_s']:.2f}" for r in one))
    at16 = [r for r in rows if r.get("shading") == "msaa" and r["sub_rays_per_sample"] == 16
            and r["config"] == "pinhole" and r.get("sub_grays_s")]
    if at16:
        out[">= 10 G sub-rays/s at 16x (pinhole MSAA trace)"] = verdict(
            min(r["sub_grays_s"] for r in at16) >= 10.0,
            ", ".join(f"{r['scene']} {r['size']} {r['sub_grays_s']:.2f}" for r in at16))
    for r in views:
        if r["config"] == "pinhole" and r["sub_rays_per_sample"] == 4 and r["shading"] == "msaa":
            ref = next((x for x in views if x["scene"] == r["scene"] and x["config"] == "raster_gbuffer"), None)
            if ref is not None:
                out[f"{r['scene']}: 4x MSAA pinhole visibility <= 1x raster G-buffer"] = verdict(
                    r["visibility_ms"] <= ref["visibility_ms"],
                    f"{r['visibility_ms']:.3f} ms (primary_rays + gbuffer, {r['rounds']} rounds, "
                    f"{r.get('rounds_recorded', r['rounds']):g} recorded; trace alone "
                    f"{r['primary_ms']:.3f}) vs {ref['visibility_ms']:.3f} ms (visibility + gbuffer); frames "
                    f"{r['total_ms']:.3f} vs {ref['total_ms']:.3f} ms")
    return out


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=20, warmup=3, counts=None,
        ssaa=(4,), configs=None, custom=None, backend=None, progress=True, suites=SUITES,
        table5_size=TABLE5_SIZE, tiles=True, builds=("sah",), frame_culling=(None,)) -> dict:
    """`configs`/`counts` (views suite rows; default VIEW_CONFIGS x VIEW_COUNTS); `builds`: every
    row once per BVH build (accel/bvh.BUILDS; rows carry `bvh_build`); `frame_culling`: every rays
    row once per value of RenderSettings.tile_culling (None: the renderer's own choice, False: per-ray
    traversal, True: tile culling; rows carry the one made, `tile_culling`); `custom` =
    (camera model, fov_y or None): that camera instead (beside the raster reference), as
    `rayvr bench primary --camera-model ... --camera-param ...` asks. `tiles`: also trace each
    camera's central rays standalone without and with tile culling."""
    table = dict(CONFIGS)
    if custom is not None:
        table["custom"] = (custom[0], custom[1], "rays")
        configs = ("raster_gbuffer", "custom")
    configs = configs or VIEW_CONFIGS
    counts = counts or VIEW_COUNTS
    plan = []  # (suite, per-eye size, config, sub-rays, shade every sub-ray)
    if "table5" in suites:
        plan += [("table5", tuple(table5_size), c, n, False) for c, n in TABLE5]
    if "views" in suites:
        for c in configs:
            raster = table[c][2] == "raster"
            plan += [("views", tuple(size), c, n, False) for n in ((1,) if raster else counts)]
            plan += [("views", tuple(size), c, n, True) for n in ([] if raster else ssaa) if n > 1]
    gl = create_context(backend)
    rows, skipped = [], {}
    result = {"meta": {}, "rows": rows}
    try:
        meta = {**device_meta(gl.info()), "bench": "primary", "per_eye_size": list(size),
                "table5_per_eye_size": list(table5_size), "suites": list(suites), "repeat": repeat,
                "bvh_builds": list(builds), "tile_culling": ["auto" if tc is None else tc for tc in frame_culling],
                "skipped": skipped, "materials": "all raster (visibility, not shading, is measured)",
                "what_times_include": {
                    "pass_ms": "GL timer query per pass, summed over a sampled frame's rounds; medians",
                    "primary_ms": "the primary-ray kernels alone (MSAA trace / per-round cast), kernel "
                                  "by kernel; BVH already on the GPU",
                    "visibility_ms": "raster: visibility + gbuffer passes; rays: primary_rays (trace, select) "
                                     "+ gbuffer, summed over the rounds",
                    "msaa_note": "an MSAA frame's count of rounds is polled, never waited for: rounds "
                                 "recorded before it is known and past it skip every pixel (rounds vs "
                                 "rounds_recorded); empty slots cost a 4-byte read per pass",
                    "tile_culling": "rows with tile_culling true: the frame's primary_rays culls per 16x8-pixel "
                                    "tile first (cull_ms: that kernel, summed over the channel sets; in primary_ms) "
                                    "and traces bvh2 from the tiles' entry lists; trace_* columns: the camera's "
                                    "central rays (one per sample) traced standalone by accel/gpu.py RayTracer, "
                                    "binary BVH, without / with tile culling (trace_cull_ms: its cull dispatch); "
                                    "*_node_visits, *_entry_tests, *_triangle_tests: their GPU-counted work per ray "
                                    "(trace: per ray; tree: tile entries in tree order; tiles: front to back)"}}
        result["meta"] = meta
        for name, scene, view in bench_scenes(scenes, size, skipped):
            with Renderer(scene, gl=gl) as r:
                culled = {}  # (build, config, size) -> tile-culling columns
                runs = ((b, p, tc) for b in builds for p in plan
                        for tc in ((False,) if table[p[2]][2] == "raster" else frame_culling))
                for build, (suite, eye_size, cname, n, shade_all), tc in runs:
                    model, fov, primary = table[cname]
                    rig = StereoRig(view.pose, ipd=view.ipd, fov_y=fov or view.fov_y, near=view.near, size=eye_size,
                                    camera=model)
                    r.settings = RenderSettings(primary=primary, msaa=n, ssaa=shade_all, bvh_build=build, tile_culling=tc)
                    names, med, total = time_frame(r, rig, repeat, warmup)
                    row = {"suite": suite, "scene": name, "config": cname, "camera": model.name, "primary": primary,
                           "sub_rays_per_sample": n, "shading": "ssaa" if shade_all else "msaa", "bvh_build": build,
                           "tile_culling": r.plan(camera=model).tile_culling,
                           "size": f"2x{eye_size[0]}x{eye_size[1]}", "total_ms": total,
                           "pass_ms": {k: med[k] for k in names if k in med}}
                    if primary == "rays":
                        kernel, cull_ms = primary_kernel_ms(r, rig)
                        samples = samples_per_frame(rig)
                        sub_rays = samples * n * model.channels
                        row.update(samples=samples, channels=model.channels, sub_rays=sub_rays, primary_ms=kernel, cull_ms=cull_ms,
                                   **frame_rounds(r, rig), sub_grays_s=sub_rays / (kernel * 1e6) if kernel > 0 else None,
                                   visibility_ms=med.get("primary_rays", 0.0) + med.get("gbuffer", 0.0))
                        key = (build, cname, eye_size)
                        if tiles and (suite == "table5" or n == 1) and not shade_all and not tc:
                            if key not in culled:
                                r.accel.ensure()
                                culled[key] = tile_culling(gl, r.accel.gpu, rig, scene.origin, max(2, repeat // 4))
                            row.update(culled[key])
                    else:
                        row["visibility_ms"] = med.get("visibility", 0.0) + med.get("gbuffer", 0.0)
                    rows.append(row)
                    meta["targets"] = targets(rows)
                    write_report(out_dir, "primary", result)  # after every row: a cut run keeps what it did
                    if progress:
                        rate = f", {row['sub_grays_s']:.3f} G sub-rays/s" if row.get("sub_grays_s") else ""
                        if row.get("rounds", 1) > 1 or row.get("rounds_recorded_max", 1) > 1:
                            rate += f", rounds {row['rounds']} needed / {row['rounds_recorded']:g} recorded"
                        cull = (f"; standalone {row['trace_grays_s']:.2f} / tiles {row['trace_tiles_grays_s']:.2f} GRays/s"
                                if "trace_grays_s" in row else "")
                        tag = "+tiles" if row.get("tile_culling") else ""
                        print(f"  {suite:6s} {name:8s} {build:4s} {cname + tag:20s} {n:2d}x {row['shading']} {row['size']} frame "
                              f"{total:.3f} ms, visibility {row['visibility_ms']:.3f} ms{rate}{cull}", flush=True)
    finally:
        gl.release()
    meta["targets"] = targets(rows)
    write_report(out_dir, "primary", result)
    return result
