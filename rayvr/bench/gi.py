"""`rayvr bench gi`: issue 11's benchmark of global illumination, the "Done means" figures.

Three parts (`parts`, the CLI's --configs), per scene (the benchmark views of bench/scenes.py):
  photon  the photon paper's Tables 1 (kd-tree vs hash grid, k-nearest heap) and 2 (heap vs no
          heap) over issue 11's grid, photons {128², 256², 512²} x radius {0.02, 0.05, 0.1, 0.2}
          m, through `rayvr bench photon` (bench/photon.py scene_rows): the photon map's GPU ms
          (trace + build + sort + query) apart from the direct light's shadow rays, FLIP against
          a many-photon reference with the same direct light (another photon map).
  reuse   Table 5 (empty in the paper): separate eyes (`dual`) vs `reuse` for the `photon` effect
          (512² photons, r = 0.05, hash grid) and for `path` (1 sample, 4 bounces), through `rayvr
          bench stereo` (bench/stereo.py mode_rows): each eye's ms (left: the left eye alone;
          right: what the second eye adds), the right eye's share of the left's, FLIP of each eye
          against `dual` with the same seed.
  path    `path` (4 bounces, NEE + MIS, every material) at 1/4/16 samples per pixel with and
          without the denoiser: spp is paths per pixel in one frame (`samples`: what a frame that
          must show that many samples pays), GPU ms of that frame after warm-up; beside it the same
          spp reached by accumulating that many 1-sample frames of a still view (capture's --spp:
          cost spp x the 1-sample frame). FLIP of both eyes against a converged reference
          (`reference_spp` samples) drawn with another seed (REFERENCE_SEED, never the variants').
Issue 11's targets on the H200 at 2x1440x1600 are judged met or missed in gi.md (TARGETS).
gi.json and gi.md are rewritten (atomically) after every row, so a run stopped early keeps the rows
it measured; rows of parts or scenes a run does not measure are kept from the folder's earlier
gi.json when it came from the same device, size and mode (a run split with --configs adds up).
Plots (matplotlib, the `bench` extra) after each part: ms vs FLIP per scene.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..frame.accumulation import sample_seed
from ..gl.context import create_context
from ..scene.materials import parse_config
from ..renderer import Renderer, RenderSettings
from . import photon, stereo
from .rays import time_effect_stages, time_frame
from .report import _plot, device_meta, earlier_rows, write_report
from .scenes import bench_scenes
from ..quality.measure import REFERENCE_SEED

PARTS = ("photon", "reuse", "path")
SPP = (1, 4, 16)
BOUNCES = 4
VARIANT_SEED = 0  # every variant's seed; the path reference draws REFERENCE_SEED's samples
REFERENCE_SPP = 1024
QUICK_REFERENCE_SPP = 64
REFERENCE_SAMPLES_PER_FRAME = 16  # paths per pixel in each accumulated reference frame
MODES = (("dual", 0), ("reuse", 0))  # Table 5: dual first, reuse judged against it
# issue 11's targets (H200, 2x1440x1600)
PHOTON_PATHS, PHOTON_RADIUS, PHOTON_MS = photon.TARGET
PATH_SCENE, PATH_MS = "sponza", 11.0  # path 1 spp, 4 bounces, NEE+MIS on Sponza <= 11 ms (a 90 Hz frame)
DENOISE_EXTRA_MS = 1.5  # denoised 1 spp below undenoised 16 spp in FLIP, at <= 1.5 ms more than 1 spp
REUSE_SHARE, REUSE_FLIP = 0.40, 0.02  # reuse: right eye <= 40 % of the left's cost at FLIP <= 0.02 against dual
# Table 5 also compares reuse with dual accumulated over this many samples: the error reuse makes
# (view-dependent shading, resampling) without the 1-sample noise both images carry
CONVERGED_SPP, QUICK_CONVERGED_SPP = 256, 4
TARGETS = {"photon": f"512² photons, r = {PHOTON_RADIUS}: photon map ≤ {PHOTON_MS:g} ms, both eyes",
           "path": f"path 1 spp, {BOUNCES} bounces, NEE+MIS ≤ {PATH_MS:g} ms (issue: on Sponza)",
           "denoise": f"denoised 1 spp: lower FLIP than undenoised {max(SPP)} spp, ≤ {DENOISE_EXTRA_MS:g} ms extra",
           "reuse": f"reuse: right eye ≤ {REUSE_SHARE:.0%} of the left eye's cost at FLIP ≤ {REUSE_FLIP:g} vs dual"}


def path_config(name: str, samples: int):
    """Every material on `path`: `samples` paths per pixel a frame, BOUNCES bounces, one light
    sample per vertex (NEE + BSDF sampling with MIS is the effect's own)."""
    return parse_config({"default": "path", "params": {"path": {"samples": samples, "bounces": BOUNCES,
                                                                "area_samples": 1}}},
                        f"bench:gi:path:{name}:{samples}")


def table5_configs(name: str, quick: bool) -> dict:
    """effect -> (setting, config) of Table 5: the photon target's setting, and 1-sample path."""
    paths, radius = photon.QUICK[0] if quick else (PHOTON_PATHS, PHOTON_RADIUS)
    side = int(round(paths ** 0.5))
    return {"photon": (f"{side}² photons, r = {radius}, grid", photon.config(name, paths, radius, "grid")),
            "path": (f"1 spp, {BOUNCES} bounces", path_config(name, 1))}


def both_eyes(frame) -> np.ndarray:
    return np.concatenate([frame.left.color, frame.right.color], axis=1)


def reference_plan(spp: int) -> tuple[int, int]:
    """(paths per pixel a frame, frames) of a reference of at least `spp` samples per pixel."""
    per = min(spp, REFERENCE_SAMPLES_PER_FRAME)
    return per, -(-spp // per)


def reference_seeds(spp: int) -> list:
    """The frame seeds the path reference draws (accumulation.sample_seed of REFERENCE_SEED)."""
    return [sample_seed(REFERENCE_SEED, k) for k in range(reference_plan(spp)[1])]


# ------------------------------------------------------------------------------------ parts

def photon_part(gl, name, scene, rig, quick, repeat, warmup, reference_photons, progress):
    cells = photon.QUICK if quick else photon.GRID
    for row in photon.scene_rows(gl, name, scene, rig, cells, cells, repeat, warmup, reference_photons, progress):
        yield {"part": "photon", **row}


def reuse_part(gl, name, scene, rig, quick, repeat, progress):
    from tqdm import tqdm

    configs = table5_configs(name, quick)
    spp = QUICK_CONVERGED_SPP if quick else CONVERGED_SPP
    for effect in tqdm(configs, desc=f"table 5 {name}", unit="effect", disable=not progress):
        setting, cfg = configs[effect]
        with Renderer(scene, cfg, gl=gl, settings=RenderSettings(seed=VARIANT_SEED)) as r:
            for row in stereo.mode_rows(r, rig, name, MODES, repeat, progress=False, converged_spp=spp):
                yield {"part": "reuse", "table": 5, "effect": effect, "setting": setting, **row}


def path_part(gl, name, scene, rig, quick, repeat, warmup, reference_spp, progress):
    """Rows of `path` at SPP samples per pixel, without then with the denoiser (the 1-sample frame
    first: the accumulated rows' cost is spp times it)."""
    from tqdm import tqdm

    from ..quality import metrics

    per, frames = reference_plan(reference_spp)
    bar = tqdm(total=frames + 2 * len(SPP), desc=f"path {name}", unit="step", disable=not progress)
    with bar, Renderer(scene, path_config(name, per), gl=gl, settings=RenderSettings(seed=REFERENCE_SEED)) as r:
        ref = both_eyes(r.render(rig, spp=frames, progress=bar.update))
        one: dict = {}  # denoise -> ms of the 1-sample frame
        plain: dict = {}  # spp -> ms without the denoiser
        for denoise in (False, True):
            for spp in SPP:
                r.set_materials(path_config(name, spp))
                r.settings = replace(r.settings, seed=VARIANT_SEED, denoise=denoise)
                names, med, total = time_frame(r, rig, repeat, warmup)
                image = both_eyes(r.render(rig))
                one.setdefault(denoise, total)
                plain.setdefault(spp, total)
                r.set_materials(path_config(name, 1))  # spp frames of one sample, accumulated
                accumulated = both_eyes(r.render(rig, spp=spp))
                bar.update()
                yield {"part": "path", "scene": name, "size": f"2x{rig.size[0]}x{rig.size[1]}", "spp": spp,
                       "denoise": denoise, "samples_per_frame": spp, "bounces": BOUNCES, "seed": VARIANT_SEED,
                       "frame_ms": total, "rt_path_ms": med.get("rt_path"), "accumulate_ms": med.get("accumulate"),
                       "denoise_ms": med.get("denoise"), "denoise_extra_ms": total - plain[spp] if denoise else None,
                       "pass_ms": {k: med[k] for k in names if k in med},
                       "flip": metrics.flip(ref, image),
                       "accumulated_frames": spp, "accumulated_ms": spp * one[denoise],
                       "accumulated_flip": metrics.flip(ref, accumulated)}


def wavefront_part(gl, name, scene, rig, variants, quick, repeat, warmup, progress):
    """Rows of the path (1 spp) and photon (the issue's 512^2 at 0.05, grid; quick: photon.QUICK) frames timed with each
    wavefront variant ({name: RenderSettings fields}: --ray-order, --persistent): frame and
    wavefront-kernel GPU ms; the images are the same in every variant (tests/test_ray_order.py)."""
    from tqdm import tqdm

    paths, radius = photon.QUICK[0] if quick else (PHOTON_PATHS, PHOTON_RADIUS)
    frames = {"path": path_config(name, 1), "photon": photon.config(name, paths, radius, "grid")}
    grid = [(f, v) for f in frames for v in variants]
    for frame, variant in tqdm(grid, desc=f"wavefront {name}", unit="frame", disable=not progress):
        with Renderer(scene, frames[frame], gl=gl, settings=RenderSettings(seed=VARIANT_SEED, **variants[variant])) as r:
            names, med, total = time_frame(r, rig, repeat, warmup)
            yield {"part": "wavefront", "scene": name, "size": f"2x{rig.size[0]}x{rig.size[1]}", "frame": frame,
                   "variant": variant, **variants[variant], "frame_ms": total,
                   "pass_ms": {k: med[k] for k in names if k in med}, "effect_kernel_ms": time_effect_stages(r, rig)}


# ------------------------------------------------------------------------------------ the run

def check_parts(parts) -> tuple:
    parts = tuple(dict.fromkeys(parts))
    bad = [p for p in parts if p not in PARTS]
    if bad or not parts:
        raise ValueError(f"bench gi parts must be among {', '.join(PARTS)}, got {', '.join(parts) or 'none'}")
    return parts


def kept_rows(path: Path, meta: dict, measured: set) -> tuple[list, dict]:
    """Rows (and per-part meta) of an earlier gi.json at `path` whose (part, scene) this run does
    not measure, if that run had this run's device, size and mode; else nothing."""
    rows, om = earlier_rows(path, meta, ("gl_renderer", "gl_version", "per_eye_size", "quick"),
                            lambda r: isinstance(r, dict) and r.get("part") in PARTS
                            and (r.get("part"), r.get("scene")) not in measured)
    return rows, (om.get("parts") or {}) if rows else {}


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=10, warmup=3, quick=False, parts=PARTS,
        reference_spp=None, reference_photons=None, backend=None, progress=True, gl=None, wavefront=None) -> dict:
    """Measure `parts` on `scenes` into `out_dir` (gi.json, gi.md, plots); `gl`: a context to use
    (default: a new one from `backend`, released at the end). `wavefront`: {name: RenderSettings
    fields} (--ray-order, --persistent): the path and photon frames timed with each, too."""
    parts = check_parts(parts)
    reference_spp = reference_spp or (QUICK_REFERENCE_SPP if quick else REFERENCE_SPP)
    reference_photons = reference_photons or (photon.QUICK_REFERENCE_PHOTONS if quick else photon.REFERENCE_PHOTONS)
    if reference_spp < max(SPP):
        raise ValueError(f"the path reference needs at least {max(SPP)} samples per pixel, got {reference_spp}")
    out = Path(out_dir)
    own = gl is None
    gl = gl or create_context(backend)
    rows, skipped = [], {}
    t_start = time.perf_counter()
    try:
        meta = {**device_meta(gl.info()), "bench": "gi", "per_eye_size": list(size), "repeat": repeat,
                "quick": quick, "scenes": list(scenes), "skipped": skipped, "timings_meaningful": not gl.is_software,
                "parts_run": list(parts), "seconds": {}}
        kept, parts_meta = kept_rows(out / "gi.json", meta, {(p, s) for p in parts for s in scenes})
        per, frames = reference_plan(reference_spp)
        parts_meta.update({
            "photon": {**{k: v for k, v in photon.meta(gl, size, repeat, skipped, reference_photons).items()
                          if k in ("k", "bounces", "radius_units", "reference", "error", "times")},
                       "cells": [list(c) for c in (photon.QUICK if quick else photon.GRID)]},
            "reuse": {"settings": {e: s for e, (s, _) in table5_configs("default", quick).items()},
                      "times": "left_ms: a frame of the left eye alone; right_ms: the stereo frame minus it; "
                               "second_eye_share = right_ms / left_ms (median GPU ms after warm-up)",
                      "error": f"mean FLIP of each eye against dual with the same seed; *_other_seed: against dual "
                               f"with seed {stereo.REFERENCE_SEED}"},
            "path": {"bounces": BOUNCES, "spp": list(SPP), "seed": VARIANT_SEED,
                     "reference": {"spp": per * frames, "samples_per_frame": per, "frames": frames,
                                   "seed": REFERENCE_SEED, "frame_seeds": reference_seeds(reference_spp)},
                     "error": "mean FLIP over both eyes against the reference",
                     "times": "frame_ms: median GPU ms of a frame with spp paths per pixel after warm-up; "
                              "accumulated_ms: spp x the 1-sample frame (the same spp from still frames)"}})
        parts_meta = {p: parts_meta[p] for p in PARTS if p in parts_meta}
        meta["parts"] = parts_meta
        if kept:
            meta["kept_rows"] = f"{len(kept)} rows of parts/scenes this run did not measure, from the earlier gi.json"

        note = [None]  # the plots' markdown note, from the last time they were drawn

        def write(plots: bool = False) -> None:
            meta["seconds"]["total"] = time.perf_counter() - t_start
            result = {"meta": meta, "rows": kept + rows}
            if plots:
                note[0] = draw_plots(out, result["rows"])
            write_report(out, "gi", result, md=markdown(result, note[0]))

        write()
        measure = {"photon": lambda *a: photon_part(*a, quick, repeat, warmup, reference_photons, progress),
                   "reuse": lambda *a: reuse_part(*a, quick, repeat, progress),
                   "path": lambda *a: path_part(*a, quick, repeat, warmup, reference_spp, progress)}
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            for part in parts:
                t0 = time.perf_counter()
                for row in measure[part](gl, name, scene, rig):
                    rows.append(row)
                    write()
                meta["seconds"][f"{part}/{name}"] = time.perf_counter() - t0
                write(plots=True)
            if wavefront:
                for row in wavefront_part(gl, name, scene, rig, wavefront, quick, repeat, warmup, progress):
                    rows.append(row)
                    write()
        write(plots=True)
    finally:
        if own:
            gl.release()
    return {"meta": meta, "rows": kept + rows}


# ------------------------------------------------------------------------------------ gi.md

def _f(v, fmt=".2f", none="-") -> str:
    return none if v is None else format(v, fmt)


def _verdict(ok: bool, why: str = "") -> str:
    return "**met**" if ok else "**missed**" + (f" ({why})" if why else "")


def targets(rows: list) -> list:
    """(target, where, measured, verdict) per measured row that issue 11 sets a target for, then
    each target no row measured."""
    out, seen = [], set()
    for r in rows:
        if r.get("part") == "photon" and (r["photons"], r["radius"]) == (PHOTON_PATHS, PHOTON_RADIUS) \
                and (r["scene"], r["estimator"]) not in seen:  # grid_heap is in both tables
            seen.add((r["scene"], r["estimator"]))
            ms = r.get("map_ms")
            out.append((TARGETS["photon"], f"{r['scene']}, {r['estimator']}",
                        r.get("skipped") or "not measured" if ms is None else
                        f"{ms:.2f} ms (+ {_f(r.get('shadow_ms'))} ms shadow rays)",
                        "-" if ms is None else _verdict(ms <= PHOTON_MS)))
        if r.get("part") == "path" and r["spp"] == 1 and not r["denoise"]:
            out.append((TARGETS["path"], r["scene"],
                        f"frame {r['frame_ms']:.2f} ms (rt_path {_f(r.get('rt_path_ms'))} ms)",
                        _verdict(r["frame_ms"] <= PATH_MS)))
        if r.get("part") == "path" and r["spp"] == 1 and r["denoise"]:
            sixteen = next((q for q in rows if q.get("part") == "path" and q["scene"] == r["scene"]
                            and q["spp"] == max(SPP) and not q["denoise"]), None)
            if sixteen is not None:
                lower, cheap = r["flip"] < sixteen["flip"], r["denoise_extra_ms"] <= DENOISE_EXTRA_MS
                why = ", ".join(w for w, bad in (("FLIP not lower", not lower),
                                                 (f"> {DENOISE_EXTRA_MS:g} ms extra", not cheap)) if bad)
                out.append((TARGETS["denoise"], r["scene"], f"FLIP {r['flip']:.4f} vs {sixteen['flip']:.4f}, "
                                        f"{r['denoise_extra_ms']:+.2f} ms", _verdict(lower and cheap, why)))
        if r.get("part") == "reuse" and r["mode"] == "reuse":
            # judged on the converged images where measured: the error reuse itself makes
            converged = r.get("flip_vs_dual_converged_right")
            share, flip = r["second_eye_share"], r["flip_vs_dual_right"] if converged is None else converged
            ok_share, ok_flip = share is not None and share <= REUSE_SHARE, flip <= REUSE_FLIP
            why = ", ".join(w for w, bad in ((f"share > {REUSE_SHARE:.0%}", not ok_share),
                                             (f"FLIP > {REUSE_FLIP:g}", not ok_flip)) if bad)
            at = "1 spp" if converged is None else f"{r['converged_spp']} spp, 1 spp {r['flip_vs_dual_right']:.4f}"
            out.append((TARGETS["reuse"], f"{r['scene']}, {r['effect']}",
                        f"{_f(share, '.0%')} of the left, FLIP {flip:.4f} (right eye, {at})",
                        _verdict(ok_share and ok_flip, why)))
    return out + [(t, "-", "not measured in this run", "-") for t in TARGETS.values() if t not in {o[0] for o in out}]


def markdown(result: dict, plot_note: str | None = None) -> str:
    meta, rows = result["meta"], result["rows"]
    size = "x".join(map(str, meta["per_eye_size"]))
    lines = ["# rayvr bench gi: global illumination", "",
             f"{meta.get('gl_renderer')} ({meta.get('gl_version')}), 2x{size} stereo, scenes "
             f"{', '.join(meta['scenes'])}, {meta['repeat']} timed frames a setting, {meta['date']}; parts run: "
             f"{', '.join(meta['parts_run'])}; {meta['seconds'].get('total', 0):.0f} s so far." +
             ("" if meta.get("timings_meaningful") else
              " **A software rasterizer: the ms are for correctness only, and so are the verdicts.**"), ""]
    if meta.get("kept_rows"):
        lines += [f"Kept: {meta['kept_rows']}.", ""]
    if meta.get("skipped"):
        lines += ["Skipped scenes: " + "; ".join(f"{k}: {v}" for k, v in meta["skipped"].items()), ""]
    lines += ["## Targets (set for a GPU at 2x1440x1600)", "", "| target | where | measured | verdict |",
              "|---|---|---|---|"]
    lines += [f"| {' | '.join(t)} |" for t in targets(rows)]
    lines.append("")
    ph = [r for r in rows if r.get("part") == "photon"]
    if ph:
        lines += [f"Photon map (Tables 1 and 2). {photon_note(meta)}", ""] + photon.tables_markdown(ph)
    t5 = [r for r in rows if r.get("part") == "reuse"]
    if t5:
        lines += ["## Table 5: separate eyes (dual) vs reuse", "",
                  "Left eye: a frame of the left eye alone; right eye: what the stereo frame adds to it. FLIP: "
                  "mean over the right eye against dual with the same seed (the left eye is shaded as in dual), "
                  "at 1 spp and with both accumulated over N spp (the error the mode makes, without most of the "
                  "noise); noise floor: dual against dual with another seed.", "",
                  "| scene | effect | setting | mode | frame ms | left eye ms | right eye ms | right / left | "
                  "FLIP vs dual (right), 1 spp | noise floor | FLIP vs dual (right), N spp | noise floor, N spp | "
                  "right pixels reused |", "|" + "---|" * 13]
        for r in t5:
            n = r.get("converged_spp")
            converged = "-" if n is None else f"{r['flip_vs_dual_converged_right']:.4f} (N = {n})"
            lines.append(f"| {r['scene']} | {r['effect']} | {r['setting']} | {r['mode']} | {r['frame_ms']:.2f} | "
                         f"{r['left_ms']:.2f} | {r['right_ms']:.2f} | {_f(r['second_eye_share'], '.0%')} | "
                         f"{r['flip_vs_dual_right']:.4f} | {r['noise_floor_right']:.4f} | "
                         f"{converged} | "
                         f"{_f(r.get('noise_floor_converged_right'), '.4f')} | "
                         f"{_f(r.get('reused_fraction_right'), '.1%')} |")
        lines.append("")
    pa = [r for r in rows if r.get("part") == "path"]
    if pa:
        ref = meta["parts"]["path"]["reference"]
        lines += [f"## path: 1/4/16 spp, {BOUNCES} bounces, NEE + MIS, with and without the denoiser", "",
                  f"spp = paths per pixel in one frame (ms: that frame, both eyes); accumulated: the same spp from "
                  f"that many 1-sample frames of a still view (ms: all of them). FLIP over both eyes against "
                  f"{ref['spp']} spp ({ref['frames']} frames of {ref['samples_per_frame']}) drawn with seed "
                  f"{ref['seed']:#x} (the variants: {VARIANT_SEED}).", "",
                  "| scene | spp | denoiser | frame ms | rt_path ms | accumulate + denoise ms | FLIP | "
                  "accumulated: ms | accumulated: FLIP |", "|---|---|---|---|---|---|---|---|---|"]
        for r in sorted(pa, key=lambda r: (r["scene"], r["denoise"], r["spp"])):
            extra = (r.get("accumulate_ms") or 0.0) + (r.get("denoise_ms") or 0.0) if r["denoise"] else None
            lines.append(f"| {r['scene']} | {r['spp']} | {'on' if r['denoise'] else 'off'} | {r['frame_ms']:.2f} | "
                         f"{_f(r.get('rt_path_ms'))} | {_f(extra)} | {r['flip']:.4f} | {r['accumulated_ms']:.2f} | "
                         f"{r['accumulated_flip']:.4f} |")
        lines.append("")
    wf = [r for r in rows if r.get("part") == "wavefront"]
    if wf:
        lines += ["## Wavefront ray order and persistent threads (the same images in every variant)", "",
                  "| scene | frame | variant | frame ms | wavefront ms | of it: order ms |", "|---|---|---|---|---|---|"]
        for r in wf:
            k = r["effect_kernel_ms"]
            lines.append(f"| {r['scene']} | {r['frame']} | {r['variant']} | {r['frame_ms']:.2f} | "
                         f"{sum(v for n, v in k.items() if n.startswith('rt_')):.2f} | "
                         f"{sum(v for n, v in k.items() if n.endswith('.order')):.2f} |")
        lines.append("")
    if plot_note:
        lines += ["## Plots", "", plot_note, ""]
    secs = meta.get("seconds", {})
    if len(secs) > 1:
        lines += ["Wall seconds per part and scene: "
                  + ", ".join(f"{k} {v:.0f}" for k, v in secs.items() if k != "total"), ""]
    return "\n".join(lines)


def photon_note(meta: dict) -> str:
    m = meta["parts"]["photon"]
    return (f"Cells: photons x radius (m) {', '.join(f'{int(round(p ** 0.5))}²x{r:g}' for p, r in m['cells'])}. "
            f"Reference: {m['reference']}. Error: {m['error']}. k = {m['k']}, {m['bounces']} photon bounces.")


def plot_points(rows: list, scene: str) -> dict:
    """Plot rows per file stem: the photon settings' map ms vs FLIP by estimator; path ms vs FLIP
    per frame and accumulated, with and without the denoiser."""
    out: dict = {}
    for r in rows:
        if r.get("scene") != scene:
            continue
        if r.get("part") == "photon" and r.get("map_ms") is not None:
            out.setdefault(f"gi_photon_{scene}", {})[r["estimator"], r["photons"], r["radius"]] = \
                {"ms": r["map_ms"], "flip": r["flip"], "series": r["estimator"]}
        if r.get("part") == "path":
            dn = " + denoiser" if r["denoise"] else ""
            pts = out.setdefault(f"gi_path_{scene}", {})
            pts["frame", r["spp"], dn] = {"ms": r["frame_ms"], "flip": r["flip"], "series": f"spp a frame{dn}"}
            pts["acc", r["spp"], dn] = {"ms": r["accumulated_ms"], "flip": r["accumulated_flip"],
                                        "series": f"accumulated frames{dn}"}
    return {k: list(v.values()) for k, v in out.items()}


def draw_plots(out: Path, rows: list) -> str:
    """Draw the plots; returns the markdown note listing them (or saying why there are none)."""
    try:
        import matplotlib
    except ImportError:
        return "Plots skipped: matplotlib is not installed (pip install 'rayvr[bench]')."
    matplotlib.use("Agg")
    files = []
    for scene in dict.fromkeys(r.get("scene") for r in rows):
        for stem, pts in plot_points(rows, scene).items():
            what = "photon map" if "photon" in stem else "path"
            files.append(_plot(out, "gi", pts, {"x": "ms", "y": "flip", "group": "series", "logx": True, "file": stem,
                                                "title": f"{scene}: {what} GPU ms vs FLIP"}))
    return "\n".join(f"- [{p.name}]({p.name})" for p in files) or "No plot yet."
