"""`rayvr bench photon`: the photon-mapping paper's tables for rayvr's `photon` effect.

Per scene, every diffuse material on `photon` (the scene's mirrors on `reflections`, as in
`rayvr bench rays`), at the paper's photon counts and radii (Tables 1 and 2 list these cells;
its radii are in its scenes' units, as the effect's: metres in the room and Sponza; `rayvr bench
gi` measures issue 11's full grid, GRID, through `scene_rows` here):
  Table 1  kd-tree (built on the CPU, searched on the GPU) vs hash grid, both with the k-nearest heap
  Table 2  hash grid with the heap vs without (all photons within r)
Each row: GPU ms per pass from GL timer queries after the frame times settle -- photon_trace,
build (photon_cells + photon_scan: cell keys, counts, start indices), sort (photon_sort), query
(the density estimate: the rt_photon pass's pixel kernel), the whole rt_photon pass, the frame --
and the photon map's cost `map_ms` = trace + build + sort + query (kd-tree: trace + query, its
CPU build apart), apart from `shadow_ms`, the direct light's shadow rays (rt_photon's
shadow kernels, which every effect with shadows pays); the kd-tree's CPU build (wall ms, photons
read back included), and the error: mean FLIP over the
photon pixels of both eyes against a many-photon reference (REFERENCE_PHOTONS paths, grid,
REFERENCE_RADIUS) with another photon map (map_seed) but the variants' frame seed, so that the
direct light's shadow-ray samples are the same and the error is the photon map's alone.
Table 5 (separate eyes vs `reuse`) is in `rayvr bench gi` (rayvr/bench/gi.py).
Written as photon.json / photon.md and photon_tables.md (one table per paper table) under the
output folder, again after every setting (a run stopped early keeps what it measured).
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..gl.context import create_context
from ..frame.effects import EFFECTS
from ..scene.materials import parse_config
from ..renderer import Renderer
from .report import _atomic_write, device_meta, write_report
from .scenes import bench_scenes

# (photon paths, paper radius) of the paper's Tables 1 and 2
TABLE1 = ((512 ** 2, 0.02), (512 ** 2, 0.05), (512 ** 2, 0.1), (256 ** 2, 0.05), (256 ** 2, 0.1), (256 ** 2, 0.2),
          (128 ** 2, 0.05), (128 ** 2, 0.1), (128 ** 2, 0.2))
TABLE2 = ((512 ** 2, 0.02), (512 ** 2, 0.05), (512 ** 2, 0.1), (256 ** 2, 0.05), (256 ** 2, 0.1), (256 ** 2, 0.2))
# issue 11's grid for both tables: photons {128², 256², 512²} x radius {0.02, 0.05, 0.1, 0.2} (the paper's cells and more)
GRID = tuple((side ** 2, r) for side in (512, 256, 128) for r in (0.02, 0.05, 0.1, 0.2))
QUICK = ((4096, 0.5),)  # ~20 photons a query in the room at 64² paths
TARGET = (512 ** 2, 0.05, 3.0)  # issue 11: 512² photons at r = 0.05, both eyes <= 3 ms (the photon map's cost)
ESTIMATORS = ("grid", "grid_heap", "kdtree", "kdtree_heap")
TABLES = {1: ("Table 1: kd-tree vs hash grid (k-nearest heap)", ("kdtree_heap", "grid_heap")),
          2: ("Table 2: heap vs no heap (hash grid)", ("grid_heap", "grid"))}
REFERENCE_PHOTONS = 1 << 22
QUICK_REFERENCE_PHOTONS = 1 << 15
REFERENCE_RADIUS = 0.05  # metres: ~16x the photons of 512^2 at 0.05 within it
REFERENCE_MAP_SEED = 1  # the reference's photon map differs; its direct light (frame seed 0) is the variants'
K = 32  # the heap's size (the paper does not say its k)
SLOW_FRAME_MS = 1000.0  # a setting slower than this is timed on one frame, not `repeat`
SKIP_FRAME_MS = 10000.0  # an estimator this slow at some setting skips the costlier ones (more photons, larger r)
MIRRORS = {"default": ("mirror*", "gold"), "sponza": ()}
EMITTERS = {"default": ("light",)}
BOUNCES = 3


def config(name: str, photons: int, radius: float, estimator: str, map_seed: int = 0):
    params = {"photons": photons, "radius": radius, "k": K, "bounces": BOUNCES, "map_seed": map_seed,
              "estimator": ESTIMATORS.index(estimator)}
    mats = {m: {"effect": "reflections", "bounces": 1} for m in MIRRORS.get(name, ())}
    mats.update({m: "raster" for m in EMITTERS.get(name, ())})
    return parse_config({"default": "photon", "params": {"photon": params}, "materials": mats},
                        f"bench:photon:{name}:{photons}:{radius}:{estimator}")


def measure(r: Renderer, rig, cfg, seed: int, repeat: int, warmup: int) -> dict:
    """GPU ms per pass (median over `repeat` frames after warm-up) and per kernel of rt_photon,
    the stereo colour image and the photon pixels' mask, with the renderer `r` set to `cfg` and
    `seed` (one renderer per scene: the programs are built once, every setting has the same frame
    graph). A setting whose first frame takes over SLOW_FRAME_MS is timed on that frame alone (and
    its kernels on one more).
    A kd-tree setting builds its tree on the CPU once (frame/effects/photon/kdtree.py keeps it while the
    photons stay the same); kd_cpu_ms times one such build."""
    from .rays import time_effect_stages

    r.set_materials(cfg)
    r.settings = replace(r.settings, seed=seed)
    frame = r.render(rig, aux=("effect", "position"))  # deterministic per seed: every frame of it is this image
    slow = sum(frame.timings.values()) > SLOW_FRAME_MS
    kd = any(a.params.get("estimator", 0) >= 2 for a in r.assignments if a.effect == "photon")
    ms: dict = {}
    if slow or r.gl.is_software:
        runs = [frame.timings]
    else:
        r.warm_up(rig, min_frames=warmup)
        runs = [r.read_ms(r.record(rig)) for _ in range(repeat)]
    for t in runs:
        for k, v in t.items():
            ms.setdefault(k, []).append(v)
    stages = time_effect_stages(r, rig, repeat=1 if slow or r.gl.is_software else min(repeat, 5))
    kd_cpu = None
    if kd:
        from ..frame.effects.photon.kdtree import kdtree_records

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
    from ..frame.effects.photon.setup import photon_setup

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
    from ..quality import metrics

    ms, stages = m["ms"], m["stages"]
    kd = m["kd_cpu_ms"] is not None
    shadow = [v for k, v in stages.items() if k.startswith("rt_photon.shadow")]
    out = {"scene": name, "size": f"2x{size[0]}x{size[1]}", "photons": photons,
           "photons_side": int(round(math.sqrt(photons))), "radius": radius, "estimator": estimator,
           "trace_ms": ms.get("photon_trace"), "build_ms": ms.get("photon_cells", 0.0) + ms.get("photon_scan", 0.0),
           "sort_ms": ms.get("photon_sort"), "query_ms": stages.get("rt_photon.pixel"),
           "shadow_ms": sum(shadow) if shadow else None,
           "rt_photon_ms": ms.get("rt_photon"), "kd_upload_ms": ms.get("photon_kdtree") if kd else None,
           "kd_cpu_build_ms": m["kd_cpu_ms"], "frame_ms": float(sum(ms.values())), "frames_timed": m["frames"],
           "visited": m["visited"], "accepted": m["accepted"]}
    out["photon_ms"] = sum(v or 0.0 for k, v in out.items() if k in ("trace_ms", "build_ms", "sort_ms", "rt_photon_ms"))
    # the photon map's GPU cost: what its estimator runs; the kd-tree's CPU build is apart (kd_cpu_build_ms;
    # its pass's timer, kd_upload_ms, also spans the GPU waiting for the photons' readback)
    parts = ("trace_ms", "query_ms") if kd else ("trace_ms", "build_ms", "sort_ms", "query_ms")
    out["map_ms"] = None if any(out[k] is None for k in parts) else sum(out[k] for k in parts)
    out["flip"] = metrics.flip(ref["image"], m["image"], mask=ref["mask"]) if ref["mask"].any() else None
    return out


def jobs(cells1, cells2) -> list:
    """(table, photons, radius, estimator) of Tables 1 and 2 over their cells, cheapest first (a
    slow estimator then skips what costs more)."""
    out = [(1, p, r, e) for p, r in cells1 for e in TABLES[1][1]] + [(2, p, r, e) for p, r in cells2 for e in TABLES[2][1]]
    return sorted(out, key=lambda j: (j[1] * j[2] ** 2, j[0]))


def scene_rows(gl, name, scene, rig, cells1, cells2, repeat=10, warmup=3, ref_photons=REFERENCE_PHOTONS,
               progress=True):
    """Yield the rows of Tables 1 (`cells1`) and 2 (`cells2`) of one scene as they are measured,
    cheapest first: the reference first, then each (photons, radius, estimator) once (grid_heap
    is in both tables: measured once, a row in each)."""
    from tqdm import tqdm

    size = rig.size
    with Renderer(scene, config(name, ref_photons, REFERENCE_RADIUS, "grid"), gl=gl) as r:
        # the same frame seed as the variants (the same direct-light samples: with seed 1 its
        # shadow-ray noise alone was FLIP ~0.13 here), another photon map (map_seed)
        ref = measure(r, rig, config(name, ref_photons, REFERENCE_RADIUS, "grid", REFERENCE_MAP_SEED),
                      seed=0, repeat=1, warmup=1)
        done: dict = {}
        too_slow: dict = {}  # estimator -> settings whose frame passed SKIP_FRAME_MS
        with tqdm(jobs(cells1, cells2), desc=f"photon tables {name}", unit="setting", disable=not progress) as bar:
            for table, photons, radius, est in bar:
                key = (photons, radius, est)
                if key not in done:
                    if any(p <= photons and q <= radius for p, q in too_slow.get(est, ())):
                        done[key] = {"scene": name, "photons": photons, "photons_side": int(round(math.sqrt(photons))),
                                     "radius": radius, "estimator": est, "photon_ms": None, "map_ms": None,
                                     "flip": None, "skipped": f"a cheaper setting took over {SKIP_FRAME_MS:.0f} ms a frame"}
                    else:
                        m = measure(r, rig, config(name, photons, radius, est), seed=0, repeat=repeat, warmup=warmup)
                        done[key] = row(name, size, photons, radius, est, m, ref)
                        if done[key]["frame_ms"] > SKIP_FRAME_MS:
                            too_slow.setdefault(est, []).append((photons, radius))
                yield {"table": table, **done[key]}


def paper_order(rows: list) -> list:
    """Rows in the paper's order: table, scene, photons (most first), radius."""
    return sorted(rows, key=lambda x: (x["table"], x["scene"], -x["photons"], x["radius"]))


def meta(gl, size, repeat, skipped, ref_photons) -> dict:
    return {**device_meta(gl.info()), "per_eye_size": list(size), "repeat": repeat,
            "skipped": skipped, "k": K, "bounces": BOUNCES,
            "radius_units": "scene units (metres), as the paper's",
            "reference": f"{ref_photons} photon paths, grid, radius {REFERENCE_RADIUS}, frame seed 0 as the variants "
                         f"(the same direct light), photon map_seed {REFERENCE_MAP_SEED} (variants: 0)",
            "error": "mean FLIP over the photon pixels of both eyes",
            "times": "GPU ms from GL timer queries (median of the timed frames after warm-up); build = "
                     "photon_cells + photon_scan; query = the rt_photon pixel kernel (the density estimate and "
                     "the direct light's setup); shadow = rt_photon's shadow kernels (the direct light's "
                     "shadow rays); map = trace + build + sort + query (kd-tree: trace + query; its CPU build apart); "
                     "kd_cpu_build_ms = wall ms of the CPU kd-tree build"}


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=10, warmup=3, quick=False, backend=None,
        progress=True) -> dict:
    gl = create_context(backend)
    rows, skipped = [], {}
    ref_photons = QUICK_REFERENCE_PHOTONS if quick else REFERENCE_PHOTONS
    try:
        info = {**meta(gl, size, repeat, skipped, ref_photons), "bench": "photon"}
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            for r in scene_rows(gl, name, scene, rig, QUICK if quick else TABLE1, QUICK if quick else TABLE2,
                                repeat, warmup, ref_photons, progress):
                rows.append(r)
                result = {"meta": info, "rows": paper_order(rows)}
                write_report(out_dir, "photon", result)
                _atomic_write(Path(out_dir) / "photon_tables.md",
                              lambda f: f.write("\n".join(["# Photon map: the paper's tables for rayvr", ""]
                                                          + tables_markdown(rows)).encode()))
    finally:
        gl.release()
    return {"meta": info, "rows": paper_order(rows)}


def _cell(r) -> str:
    if r is None:
        return "-"
    if r.get("skipped"):
        return "skipped (slower than 10 s a frame at a cheaper setting)"
    ms = "-" if r.get("map_ms") is None else f"{r['map_ms']:.2f} ms"
    shadow = "" if r.get("shadow_ms") is None else f" + {r['shadow_ms']:.2f} ms shadows"
    cpu = "" if r.get("kd_cpu_build_ms") is None else f" (+ CPU build {r['kd_cpu_build_ms']:.0f} ms)"
    flip = "-" if r["flip"] is None else f"{r['flip']:.4f}"
    seen = "" if r.get("visited") is None else f", {r['accepted']:.0f}/{r['visited']:.0f} photons"
    return f"{ms}{cpu}{shadow} (FLIP {flip}{seen})"


def tables_markdown(rows: list) -> list:
    """Markdown lines of Tables 1 and 2 with rayvr's figures: per cell the photon map's ms (trace
    + build + sort + query; the kd-tree's CPU build apart) + the direct light's shadow rays, FLIP,
    photons a query accepts / visits (mean over sampled pixels); the query kernel's ms per column."""
    lines = []
    for table, (title, cols) in TABLES.items():
        mine = paper_order([r for r in rows if r["table"] == table])
        lines += [f"## {title}", "", "ms = the photon map (trace + build + sort + query) + the direct light's "
                  "shadow rays, both eyes", "",
                  "| scene | photons | radius | " + " | ".join(cols) + " | query ms |", "|---|---|---|" + "---|" * (len(cols) + 1)]
        keys = list(dict.fromkeys((r["scene"], r["photons_side"], r["radius"]) for r in mine))
        for k in keys:
            by = {r["estimator"]: r for r in mine if (r["scene"], r["photons_side"], r["radius"]) == k}
            q = " / ".join(f"{by[c]['query_ms']:.2f}" if by.get(c) and by[c].get("query_ms") is not None else "-"
                           for c in cols)
            lines.append(f"| {k[0]} | {k[1]}² | {k[2]} | " + " | ".join(_cell(by.get(c)) for c in cols) + f" | {q} |")
        lines.append("")
    return lines
