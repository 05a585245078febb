"""`rayvr bench photon`: the photon-mapping paper's tables for rayvr's `photon` effect.

Per scene, every diffuse material on `photon` (the scene's mirrors on `reflections`, as in
`rayvr bench rays`), at the paper's photon counts and radii (Tables 1 and 2 list these cells;
its radii are in its scenes' units, as the effect's: metres in the room and Sponza):
  Table 1  kd-tree (built on the CPU, searched on the GPU) vs hash grid, both with the k-nearest heap
  Table 2  hash grid with the heap vs without (all photons within r)
Each row: GPU ms per pass from GL timer queries after the frame times settle -- photon_trace,
build (photon_cells + photon_scan: cell keys, counts, start indices), sort (photon_sort), query
(the density estimate: the rt_photon pass's pixel kernel), the whole rt_photon pass, the frame --
the kd-tree's CPU build (wall ms, photons read back included), and the error: mean FLIP over the
photon pixels of both eyes against a many-photon reference (REFERENCE_PHOTONS paths, grid,
REFERENCE_RADIUS) with another photon map (map_seed) but the variants' frame seed, so that the
direct light's shadow-ray samples are the same and the error is the photon map's alone. Table 5 (separate eyes vs `reuse`) waits for `reuse`.
Written as photon.json / photon.md (one table per paper table) under the output folder.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..context import create_context
from ..effects import EFFECTS
from ..materials import parse_config
from ..renderer import Renderer
from .report import device_meta, write_report
from .scenes import bench_scenes

# (photon paths, paper radius) of the paper's Tables 1 and 2
TABLE1 = ((512 ** 2, 0.02), (512 ** 2, 0.05), (512 ** 2, 0.1), (256 ** 2, 0.05), (256 ** 2, 0.1), (256 ** 2, 0.2),
          (128 ** 2, 0.05), (128 ** 2, 0.1), (128 ** 2, 0.2))
TABLE2 = ((512 ** 2, 0.02), (512 ** 2, 0.05), (512 ** 2, 0.1), (256 ** 2, 0.05), (256 ** 2, 0.1), (256 ** 2, 0.2))
QUICK = ((4096, 0.5),)  # ~20 photons a query in the room at 64² paths
REFERENCE_PHOTONS = 1 << 22
REFERENCE_RADIUS = 0.05  # metres: ~16x the photons of 512^2 at 0.05 within it
REFERENCE_MAP_SEED = 1  # the reference's photon map differs; its direct light (frame seed 0) is the variants'
K = 32  # the heap's size (the paper does not say its k)
SLOW_FRAME_MS = 1000.0  # a setting slower than this is timed on one frame, not `repeat`
KD_FRAMES = 3  # frames timed for the kd-tree settings (each builds its tree on the CPU)
SKIP_FRAME_MS = 10000.0  # an estimator this slow at some setting skips the costlier ones (more photons, larger r)
MIRRORS = {"default": ("mirror*", "gold"), "sponza": ()}
EMITTERS = {"default": ("light",)}
BOUNCES = 3


def config(name: str, photons: int, radius: float, estimator: str, map_seed: int = 0):
    params = {"photons": photons, "radius": radius, "k": K, "bounces": BOUNCES, "map_seed": map_seed,
              "estimator": ("grid", "grid_heap", "kdtree", "kdtree_heap").index(estimator)}
    mats = {m: {"effect": "reflections", "bounces": 1} for m in MIRRORS.get(name, ())}
    mats.update({m: "raster" for m in EMITTERS.get(name, ())})
    return parse_config({"default": "photon", "params": {"photon": params}, "materials": mats},
                        f"bench:photon:{name}:{photons}:{radius}:{estimator}")


def measure(r: Renderer, rig, cfg, seed: int, repeat: int, warmup: int) -> dict:
    """GPU ms per pass (median over `repeat` frames) and per kernel of rt_photon, the stereo
    colour image and the photon pixels' mask, with the renderer `r` set to `cfg` and `seed` (one
    renderer per scene: the programs are built once, every setting has the same frame graph).
    A setting whose first frame takes over SLOW_FRAME_MS is timed on that frame alone."""
    from .rays import time_effect_stages

    r.set_materials(cfg)
    r.settings = replace(r.settings, seed=seed)
    frame = r.render(rig, aux=("effect", "position"))  # deterministic per seed: every frame of it is this image
    slow = sum(frame.timings.values()) > SLOW_FRAME_MS
    kd = any(a.params.get("estimator", 0) >= 2 for a in r.assignments if a.effect == "photon")
    ms: dict = {}
    if slow or r.gl.is_software:
        runs = [frame.timings]
    elif kd:  # each frame reads the photons back and builds the tree on the CPU (seconds): the GPU
        # is warm from the settings before; a few frames time its passes
        runs = [r.read_ms(r.record(rig)) for _ in range(min(repeat, KD_FRAMES))]
    else:
        r.warm_up(rig, min_frames=warmup)
        runs = [r.read_ms(r.record(rig)) for _ in range(repeat)]
    for t in runs:
        for k, v in t.items():
            ms.setdefault(k, []).append(v)
    stages = {} if slow else time_effect_stages(r, rig, repeat=1 if r.gl.is_software else min(repeat, 5))
    kd_cpu = None
    if kd:
        from ..passes.photon_kdtree import kdtree_records

        t0 = time.perf_counter()
        kdtree_records(r.resource("photons").read())
        kd_cpu = (time.perf_counter() - t0) * 1e3
    image = np.concatenate([frame.left.color, frame.right.color], axis=1)
    mask = np.concatenate([frame.left.aux["effect"], frame.right.aux["effect"]], axis=1) == EFFECTS["photon"].id
    visits = query_counts(r, rig, frame.left)
    return {**visits, "ms": {k: float(np.median(v)) for k, v in ms.items()}, "stages": stages, "image": image, "mask": mask,
            "kd_cpu_ms": kd_cpu, "frames": len(runs)}


QUERY_SAMPLES = 256  # photon pixels per setting whose search is replayed in numpy


def query_counts(r: Renderer, rig, eye) -> dict:
    """Photons a query visits (the 9 runs of the hash grid) and accepts (within r), mean over
    QUERY_SAMPLES photon pixels of the eye, replayed in numpy (accel/photon_map) on the frame's own
    photon map: what the query's cost follows."""
    from ..accel import photon_map as pm
    from ..effects.photon import photon_setup

    pix = eye.aux["effect"] == EFFECTS["photon"].id
    if not pix.any():
        return {"visited": None, "accepted": None}
    ps = photon_setup(r.sizing(rig.size))
    radius = max(a.params.get("radius") for a in r.assignments if a.effect == "photon")
    ph = pm.unpack_photons(r.resource("photons").read())
    pos = ph["position"][ph["extra"] != 0]
    order, start = pm.build_grid(ps.grid, pm.grid_cells(ps.grid, pos))
    pos = pos[order]
    q = eye.aux["position"][pix][:, :3] - r.scene.origin
    q = q[np.linspace(0, len(q) - 1, min(QUERY_SAMPLES, len(q))).astype(int)]
    visited = [sum(int(start[b]) - int(start[a]) for a, b in pm.neighbour_runs(ps.grid, x)) for x in q]
    accepted = [len(pm.grid_query(ps.grid, pos, start, x, radius)) for x in q]
    return {"visited": float(np.mean(visited)), "accepted": float(np.mean(accepted))}


def row(name, size, photons, radius, estimator, m, ref) -> dict:
    from . import metrics

    ms = m["ms"]
    out = {"scene": name, "size": f"2x{size[0]}x{size[1]}", "photons": photons,
           "photons_side": int(round(math.sqrt(photons))), "radius": radius, "estimator": estimator,
           "trace_ms": ms.get("photon_trace"), "build_ms": ms.get("photon_cells", 0.0) + ms.get("photon_scan", 0.0),
           "sort_ms": ms.get("photon_sort"), "query_ms": m["stages"].get("rt_photon.pixel"),
           "rt_photon_ms": ms.get("rt_photon"), "kd_upload_ms": ms.get("photon_kdtree") if m["kd_cpu_ms"] else None,
           "kd_cpu_build_ms": m["kd_cpu_ms"], "frame_ms": float(sum(ms.values())), "frames_timed": m["frames"],
           "visited": m["visited"], "accepted": m["accepted"]}
    out["photon_ms"] = sum(v or 0.0 for k, v in out.items() if k in ("trace_ms", "build_ms", "sort_ms", "rt_photon_ms"))
    out["flip"] = metrics.flip(ref["image"], m["image"], mask=ref["mask"]) if ref["mask"].any() else None
    return out


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=10, warmup=3, quick=False, backend=None,
        progress=True) -> dict:
    from tqdm import tqdm

    gl = create_context(backend)
    rows, skipped = [], {}
    t1 = QUICK if quick else TABLE1
    t2 = QUICK if quick else TABLE2
    jobs = [(1, p, r, e) for p, r in t1 for e in ("kdtree_heap", "grid_heap")] + \
           [(2, p, r, e) for p, r in t2 for e in ("grid_heap", "grid")]
    jobs.sort(key=lambda j: (j[1] * j[2] ** 2, j[0]))  # cheapest first: slow estimators skip what costs more
    ref_photons = 1 << 15 if quick else REFERENCE_PHOTONS
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            first = len(rows)
            with Renderer(scene, config(name, ref_photons, REFERENCE_RADIUS, "grid"), gl=gl) as r:
                # the same frame seed as the variants (the same direct-light samples: with seed 1 its
                # shadow-ray noise alone was FLIP ~0.13 here), another photon map (map_seed)
                ref = measure(r, rig, config(name, ref_photons, REFERENCE_RADIUS, "grid", REFERENCE_MAP_SEED),
                              seed=0, repeat=1, warmup=1)
                done: dict = {}
                bar = tqdm(jobs, desc=f"bench photon {name}", unit="setting", disable=not progress)
                too_slow: dict = {}  # estimator -> settings whose frame passed SKIP_FRAME_MS
                for table, photons, radius, est in bar:
                    key = (photons, radius, est)
                    if key not in done:  # grid_heap is in both tables: measured once
                        if any(p <= photons and q <= radius for p, q in too_slow.get(est, ())):
                            done[key] = {"scene": name, "photons": photons, "photons_side": int(round(math.sqrt(photons))),
                                         "radius": radius, "estimator": est, "photon_ms": None, "flip": None,
                                         "skipped": f"a cheaper setting took over {SKIP_FRAME_MS:.0f} ms a frame"}
                        else:
                            m = measure(r, rig, config(name, photons, radius, est), seed=0, repeat=repeat,
                                        warmup=warmup)
                            done[key] = row(name, size, photons, radius, est, m, ref)
                            if done[key]["frame_ms"] > SKIP_FRAME_MS:
                                too_slow.setdefault(est, []).append((photons, radius))
                    rows.append({"table": table, **done[key]})
                bar.close()
            rows[first:] = sorted(rows[first:], key=lambda x: (x["table"], -x["photons"], x["radius"]))  # the paper's order
        meta = {**device_meta(gl.info()), "bench": "photon", "per_eye_size": list(size), "repeat": repeat,
                "skipped": skipped, "k": K, "bounces": BOUNCES,
                "radius_units": "scene units (metres), as the paper's",
                "reference": f"{ref_photons} photon paths, grid, radius {REFERENCE_RADIUS}, frame seed 0 as the variants "
                             f"(the same direct light), photon map_seed {REFERENCE_MAP_SEED} (variants: 0)",
                "error": "mean FLIP over the photon pixels of both eyes",
                "times": "GPU ms from GL timer queries (median of the timed frames after warm-up); build = "
                         "photon_cells + photon_scan; query = the rt_photon pixel kernel (density estimate + "
                         "direct-light setup); kd_cpu_build_ms = wall ms of the CPU kd-tree build"}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "photon", result)
    _write_tables(Path(out_dir), rows)
    return result


def _write_tables(out: Path, rows: list) -> None:
    """photon_tables.md: the paper's Tables 1 and 2 with rayvr's figures (ms = the photon passes:
    trace + build + sort + rt_photon; photons a query accepts / visits, mean over sampled pixels)."""
    from .report import _atomic_write

    def cell(r):
        if r is None:
            return "-"
        if r.get("skipped"):
            return "skipped (slower than 10 s a frame at a cheaper setting)"
        flip = "-" if r["flip"] is None else f"{r['flip']:.4f}"
        seen = "" if r.get("visited") is None else f", {r['accepted']:.0f}/{r['visited']:.0f} photons"
        return f"{r['photon_ms']:.2f} ms (FLIP {flip}{seen})"

    lines = ["# Photon map: the paper's tables for rayvr", ""]
    for table, title, cols in ((1, "Table 1: kd-tree vs hash grid (k-nearest heap)", ("kdtree_heap", "grid_heap")),
                               (2, "Table 2: heap vs no heap (hash grid)", ("grid_heap", "grid"))):
        lines += [f"## {title}", "", "| scene | photons | radius | " + " | ".join(cols) + " | query ms |",
                  "|---|---|---|" + "---|" * (len(cols) + 1)]
        keys = []
        for r in rows:
            k = (r["scene"], r["photons_side"], r["radius"])
            if r["table"] == table and k not in keys:
                keys.append(k)
        for k in keys:
            by = {r["estimator"]: r for r in rows if r["table"] == table and (r["scene"], r["photons_side"], r["radius"]) == k}
            q = " / ".join(f"{by[c]['query_ms']:.2f}" if by.get(c) and by[c].get("query_ms") is not None else "-"
                           for c in cols)
            lines.append(f"| {k[0]} | {k[1]}² | {k[2]} | " + " | ".join(cell(by.get(c)) for c in cols) + f" | {q} |")
        lines.append("")
    text = "\n".join(lines)
    _atomic_write(out / "photon_tables.md", lambda f: f.write(text.encode()))
