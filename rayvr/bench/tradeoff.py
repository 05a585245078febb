"""`rayvr bench tradeoff`: the price list of accuracy.

Every knob setting (a *variant*: a material config plus render settings plus a resolution
scale) is rendered on the same stereo rig; its cost is the median GPU time of the whole frame
(sum of the passes' timer queries) and its error is measured against the reference image (the
most accurate setting rayvr has, from rayvr/quality/reference_images.py) with mean FLIP at the headset's pixels
per degree, PSNR and SSIM, over the whole image and over the pixels the knob touches.

How one variant is measured (rayvr/quality/measure.py) is the renderer's own, shared with `--budget-ms`
(rayvr/quality/budget.py); this module is the sweep over the knobs and its report.
"""
from __future__ import annotations

import contextlib
import fnmatch
from dataclasses import replace

import numpy as np

from ..quality import metrics
from ..quality.metric_pool import judge
from ..app.cluster import DEFAULT_CONNECT_TIMEOUT_S
from ..frame.effects import traced_effects
from ..settings import merged
from ..scene.materials import EFFECTS, MaterialConfig, config_with, implemented_effects  # noqa: F401
from .head_poses import POSE_SCHEME, POSE_SEED, draw_poses, pose_kind
from .report import effect_share, share_text
from ..quality.measure import (BENCH_QUALITY, COMPARE_SETTINGS, QUICK_REFERENCE_SPP, REFERENCE_SPP, WARMUP_FRAMES,
                               Measured, Reference, RendererPool, Variant, camera_refusal, local_measurer,
                               measure_reference, reference_per_frame, reference_variant)


def material_mask(scene, material_map: np.ndarray, names) -> np.ndarray | None:
    if not names:
        return None
    index = [i for i, n in enumerate(scene.material_names()) if any(fnmatch.fnmatchcase(n, g) for g in names)]
    return np.isin(material_map, index)


def error_row(ref: Measured, test: Measured, scene, variant: Variant, ppd: float, with_flip: bool = True):
    """A Future of the row's metrics of `test` against `ref` (over the pixels `variant` touches
    too), computed in a worker process where there is one (quality/metric_pool.py)."""
    mask = material_mask(scene, ref.material, variant.touches)
    if mask is not None and not mask.any():
        mask = None
    which = ("flip", "psnr", "ssim") if with_flip else ("psnr", "ssim")
    return judge(metrics.compare, ref.image, test.image, mask, ppd, which)


# ------------------------------------------------------------------------------- the knobs


def variants(scene, base: MaterialConfig, quick: bool = False, repeat: int = 10) -> list[Variant]:
    """Every knob rayvr has today, each swept along its range (effects not implemented yet are
    left out; they appear here as they land)."""
    out: list[Variant] = []
    effects = implemented_effects()
    for e in effects:  # the whole scene on one rung of the ladder
        out.append(Variant("effect", e, config_with(base, default=e, materials={n: e for n in base.by_name})))
    for effect in effects:
        # Sweep a parameter where the effect is in use: the materials the config gives it, or
        # (when it gives it none) the whole scene.
        users = tuple(n for n, (e, _) in base.by_name.items() if e == effect)
        on = base if (users or base.default == effect) else config_with(base, default=effect)
        touched = () if on.default == effect else users
        for param, (full, short) in EFFECTS[effect].sweep.items():  # each effect's own sweep ranges
            for v in (short if quick else full):
                out.append(Variant(f"{effect}.{param}", v, config_with(on, params={effect: {param: v}}),
                                   touches=touched))
    for s in ([0.5, 1.0] if quick else [0.5, 0.75, 1.0]):
        out.append(Variant("resolution_scale", s, base, scale=s))
    noisy = noisy_base(scene, base)
    out += frame_variants(base, quick) + noise_variants(noisy, quick, repeat)
    names = scene.material_names()
    rung = converging_rung()
    if {a.effect for a in noisy.assign(names, warn=False)} != {rung}:
        # The same knobs on the frame that converges to the reference, every material on path:
        # the trade the budget mode weighs (samples and the denoiser on every pixel).
        out += noise_variants(everywhere(base, rung), quick, repeat, knob_prefix=f"{rung}_everywhere.")
    # a camera that is not a pinhole cannot take screen-space tracing
    return [v for v in out if not camera_refusal(v, names)]


LAYOUTS = ("bvh2", "bvh4", "bvh8", "cwbvh")  # every ray kind through one layout: the speed of each (images equal)


def frame_variants(base: MaterialConfig, quick: bool = False) -> list[Variant]:
    """The frame-wide knobs: the stereo mode, MSAA, the foveated camera model, the BVH layout
    and build (speed only: every layout and build returns the same hits, so the same image), and
    the shadow probes of adaptive area-light shadows."""
    out = [Variant("stereo", m, base, replace(COMPARE_SETTINGS, stereo=m)) for m in ("warp", "reuse")]
    out += [Variant("msaa", n, base, replace(COMPARE_SETTINGS, msaa=n)) for n in ((4,) if quick else (4, 16))]
    out.append(Variant("camera", "foveated", base, camera="foveated"))
    out += [Variant("traversal", layout, base, replace(COMPARE_SETTINGS, traversal=(layout,) * 3))
            for layout in (LAYOUTS[:2] if quick else LAYOUTS)]
    out.append(Variant("bvh_build", "sbvh", base, replace(COMPARE_SETTINGS, bvh_build="sbvh")))
    # adaptive area-light shadows: 0 traces every shadow ray (the full count they are judged by)
    out += [Variant("shadow_probes", k, base, replace(COMPARE_SETTINGS, shadow_probes=k))
            for k in ((0, 2) if quick else (0, 2, 4, 8))]
    return out


NOISE_SEED = 1  # the noise knobs draw other samples than the other variants (and the reference: REFERENCE_SEED)


def everywhere(base: MaterialConfig, effect: str) -> MaterialConfig:
    """`base` with every material on `effect` (its parameters kept)."""
    return config_with(base, default=effect, materials={n: effect for n in base.by_name})


def converging_rung() -> str:
    """The sampled rung the reference renders diffuse surfaces with (path today): the frame whose
    samples, accumulated, converge to the reference."""
    from ..quality.reference_images import chain

    sampled = {e.name for e in traced_effects() if e.denoised}
    return next(e for e in chain("diffuse") if e in sampled)


def noisy_base(scene, base: MaterialConfig) -> MaterialConfig:
    """`base` if some material of `scene` uses a sampled (denoised) effect there, else the whole
    scene on the last such rung of the ladder: noise knobs on a noiseless image would measure nothing."""
    sampled = [e.name for e in traced_effects() if e.denoised]
    if not sampled or any(a.effect in sampled for a in base.assign(scene.material_names(), warn=False)):
        return base
    return everywhere(base, sampled[-1])


def noise_variants(base: MaterialConfig, quick: bool = False, repeat: int = 10, knob_prefix: str = "") -> list[Variant]:
    """The denoiser (off, then 1..5 à-trous iterations) at one sample a pixel, accumulated samples
    per pixel with and without it (the speed of a still view's convergence), and temporal
    accumulation on a still view (its image holds every frame measure() renders, one frame's cost).
    `knob_prefix` names the frame they vary when it is not the scene's own config."""
    plain = replace(COMPARE_SETTINGS, seed=NOISE_SEED)
    out = [Variant(f"{knob_prefix}denoise.iterations", k, base,
                   replace(plain, denoise=k > 0, denoise_iterations=max(k, 1)))
           for k in ((0, 4) if quick else (0, 1, 2, 3, 4, 5))]
    for spp in ((4,) if quick else (4, 16)):  # (1 sample: the denoise.iterations rows 0 and 4)
        out.append(Variant(f"{knob_prefix}spp", spp, base, plain, spp=spp))
        out.append(Variant(f"{knob_prefix}spp+denoise", spp, base, replace(plain, denoise=True), spp=spp))
    out.append(Variant(f"{knob_prefix}temporal", WARMUP_FRAMES + repeat, base,
                       replace(plain, **merged({"temporal": True}))))  # with what it implies: accumulation
    return out


def knob_selected(knob: str, knobs) -> bool:
    """Whether `knob` is among `knobs` (None: all): named itself or by its family, the part
    before a dot ("path" selects path.samples, "path_everywhere" every path_everywhere.* knob)."""
    return knobs is None or any(knob == k or knob.startswith(k + ".") for k in knobs)


def chosen_knobs(variants_: list[Variant], knobs) -> list[Variant]:
    """The variants of `knobs` (None: all); a name that selects none is an error naming the knobs there are."""
    if knobs is None:
        return variants_
    unknown = [k for k in knobs if not any(knob_selected(v.knob, (k,)) for v in variants_)]
    if unknown:
        families = sorted({v.knob for v in variants_})
        raise ValueError(f"bench tradeoff --knobs: {', '.join(unknown)} names no knob here; "
                         f"the knobs: {', '.join(families)}")
    return [v for v in variants_ if knob_selected(v.knob, knobs)]


def run_sweep(gl, scene, rig, reference: Variant, variants_: list[Variant], ppd: float, repeat=10,
              progress=True, with_flip=True, pool: RendererPool | None = None,
              measure_all=None, reference_spp: int | None = None,
              per_frame: int = BENCH_QUALITY["path_samples"]) -> tuple[list[dict], Reference]:
    """The reference measured here (measure_reference: `reference_spp` samples a pixel, default
    one frame a half, of `per_frame` samples each), the variants through `measure_all` (default:
    here too). The first row is the noise floor: the reference's two halves against each other
    (the second drawn with NOISE_FLOOR_SEED), below which no variant's error means anything. Every
    row records `effect_share` (report.effect_share): what the view shows under the row's config,
    from the reference's material ids (no render of its own)."""
    ref = measure_reference(gl, scene, rig, reference, reference_spp or 2 * per_frame, per_frame, pool)
    ref_image = ref.measured

    def shows(config) -> dict | None:  # what the view's frame shows under `config` (the reference's material ids)
        return None if ref_image.material is None else effect_share([ref_image.material], scene.material_names(),
                                                                    config)
    floor = replace(reference, knob="noise floor", value=f"reference halves, {ref.samples // 2} spp each")
    rows = [{"scene": scene.name, "knob": floor.knob, "value": floor.value, "label": floor.label,
             "gpu_ms": ref.halves[1].gpu_ms, **error_row(*ref.halves, scene, floor, ppd, with_flip).result(),
             "reference_ms": ref_image.gpu_ms, "reference_spp": ref.samples, "effect_share": shows(reference.config)}]
    measure_all = measure_all or local_measurer(gl, scene, rig, repeat, pool)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(variants_), unit="variant", desc=f"tradeoff {scene.name}")
    try:
        # each image judged in another process while the next one renders
        pending = [(v, m.gpu_ms, m.seconds, error_row(ref_image, m, scene, v, ppd, with_flip))
                   for v, m in zip(variants_, measure_all(variants_, bar))]
        # *_s: where a sweep's wall time goes (renderer set-up with its shader compiles, settle, render)
        rows += [{"scene": scene.name, "knob": v.knob, "value": v.value, "label": v.label, "gpu_ms": ms,
                  **errors.result(), "reference_ms": ref_image.gpu_ms, **{f"{k}_s": t for k, t in seconds.items()},
                  "effect_share": shows(v.config)}
                 for v, ms, seconds, errors in pending]
    finally:
        if bar is not None:
            bar.close()
    return rows, ref


# ------------------------------------------------------------------------------- entry points


def _setups(names, size, base_config, skipped, quick=False):
    """(name, scene, rig, base config, reference variant) per available benchmark scene."""
    from ..scene.materials import load_config
    from ..quality.reference_images import reference_config
    from .scenes import bench_scenes

    for name, scene, rig in bench_scenes(names, size, skipped):
        base = load_config(base_config(name) if base_config else None)
        ref = reference_config(scene, quick=quick, quality=None if quick else BENCH_QUALITY)
        yield name, scene, rig, base, reference_variant(ref)


@contextlib.contextmanager
def _workers(workers, address, connect_timeout):
    """A Ray cluster of `workers` sweep workers, or None to measure everything here."""
    if not workers:
        yield None
        return
    from ..app.cluster import Cluster, WorkerSpec

    with Cluster(workers, WorkerSpec(capture=False), address, connect_timeout) as cluster:
        yield cluster


def _measurer(cluster, name, rig, repeat):
    if cluster is None:
        return None
    from ..app.cluster import sweep_measurer
    from .scenes import load_bench_scene

    return sweep_measurer(cluster, load_bench_scene, name, rig, repeat)


@contextlib.contextmanager
def _bench_gl(out_dir, backend):
    """Check the output folder first (fail before any work), then a GL context for the run."""
    from ..gl.context import create_context
    from ..util.output import ensure_writable_dir

    ensure_writable_dir(out_dir)
    gl = create_context(backend)
    try:
        yield gl
    finally:
        gl.release()


def views_of(name: str, scene, rig, poses: int, pose_seed: int, only=None) -> list[tuple[str, object]]:
    """("fixed", the bench view) and ("pose I", a rig at seeded head pose I inside the scene:
    bench vr's poses, content and random, head_poses.py) for I < poses; `only`: those of these
    names (pose I is the same whatever `poses` is, so runs of some views add up to one of all)."""
    heads = draw_poses(scene, name, poses, pose_seed) if poses else []
    views = [("fixed", rig)] + [(f"pose {h.index}", replace(rig, pose=h.pose)) for h in heads]
    return [v for v in views if only is None or v[0] in only]


def _views_of_setups(scenes, size, base_config, skipped, quick, poses, pose_seed, only=None):
    """_setups' (name, scene, rig, base, reference) for each view of each scene, with the view's name."""
    for name, scene, fixed, base, reference in _setups(scenes, size, base_config, skipped, quick):
        for view, rig in views_of(name, scene, fixed, poses, pose_seed, only):
            yield name, scene, rig, base, reference, view


def view_kind(view: str) -> str:
    """"fixed" for the bench view, else the head pose's kind (head_poses.pose_kind: content, random)."""
    return "fixed" if view == "fixed" else pose_kind(int(view.split()[1]))


def view_label(row: dict) -> str:
    """A row's view as reports name it: "fixed", "pose 3 (random)" (rows from before kinds: "pose 3")."""
    kind = row.get("view_kind")
    return row["view"] if row["view"] == "fixed" or kind is None else f"{row['view']} ({kind})"


def view_suffix(view: str) -> str:
    """A file name's part for a view: "" for the fixed view, "_pose3" for pose 3."""
    return "" if view == "fixed" else "_" + view.replace(" ", "")


# What a folder's earlier tradeoff/budget report must share with a new run for its rows to stand
# beside the new ones: the views ((scene, view) pairs) the new run does not measure are kept, so
# runs split over device calls (--scenes default, then --scenes sponza) add up to one report.
SAME_SWEEP = ("gl_renderer", "gl_version", "per_eye_size", "quick", "repeat", "ppd", "pose_seed", "pose_scheme",
              "reference_spp")
SAME_BUDGET = SAME_SWEEP + ("grid", "rungs")


def _earlier_report(out_dir, name: str, meta: dict, same: tuple) -> tuple[list, dict]:
    """The rows (any view) and meta of the folder's earlier report `name`, if it matches `meta` on `same`."""
    from .report import earlier_rows

    return earlier_rows(f"{out_dir}/{name}.json", meta, same, lambda r: isinstance(r, dict) and "view" in r)


def _earlier_views(out_dir, name: str, meta: dict, same: tuple) -> list:
    """The rows of the folder's earlier report `name` (any view), if it matches `meta` on `same`."""
    return _earlier_report(out_dir, name, meta, same)[0]


def _unmeasured(earlier: list, measured: set, knobs=None) -> list:
    """The earlier rows of views ((scene, view) pairs) this run did not measure and, when it swept
    only `knobs`, of the knobs it left out (its noise floor row replaces theirs)."""
    return [r for r in earlier if (r.get("scene"), r["view"]) not in measured
            or (knobs is not None and r.get("knob") != "noise floor" and not knob_selected(r.get("knob", ""), knobs))]


def _with_earlier(earlier: list, rows: list, measured: set, knobs=None) -> list:
    """The earlier rows this run leaves standing (_unmeasured), then this run's rows."""
    return _unmeasured(earlier, measured, knobs) + rows


def _kept_views(earlier: list, measured: set) -> list[str]:
    return sorted({f"{r.get('scene')} {r['view']}" for r in _unmeasured(earlier, measured)})


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=10, quick=False, ppd=metrics.DEFAULT_PPD,
        base_config=None, backend=None, progress=True, workers=None, address=None,
        connect_timeout=DEFAULT_CONNECT_TIMEOUT_S, poses=0, pose_seed=POSE_SEED, reference_spp=None,
        knobs=None, views=None) -> dict:
    """Sweep every knob (or those `knobs` select: knob_selected) on each scene, from its fixed
    view and from `poses` head poses (views_of), each against the reference of the same view
    (`reference_spp` samples a pixel; default REFERENCE_SPP, --quick QUICK_REFERENCE_SPP); write
    tradeoff.json/.md and one plot per view. `views`: only those of them (views_of's `only`).
    `workers`: the variants spread over that many Ray workers (rayvr.app.cluster), the reference here.
    Views of the folder's earlier tradeoff.json that this run does not measure stay (SAME_SWEEP),
    and with `knobs` the other knobs' rows of the views it measures: meta's kept_views, kept_knobs
    and kept_from (the commits that measured them; every row names its commit) say which."""
    from .report import device_meta, write_report

    rows, skipped, measured = [], {}, set()
    reference_spp = reference_spp or (QUICK_REFERENCE_SPP if quick else REFERENCE_SPP)
    with _bench_gl(out_dir, backend) as gl, _workers(workers, address, connect_timeout) as cluster:
        meta = {**device_meta(gl.info()), "bench": "tradeoff", "per_eye_size": list(size), "repeat": repeat,
                "ppd": ppd, "skipped": skipped, "workers": workers or 0, "poses": poses, "pose_seed": pose_seed,
                "pose_scheme": POSE_SCHEME, "reference_spp": reference_spp, "knobs": list(knobs) if knobs else "all",
                "error": "vs the scene's reference (rayvr.quality.reference_images); "
                "flip/psnr/ssim over both eyes side by side; *_mask over the pixels the knob touches"}
        earlier, earlier_meta = _earlier_report(out_dir, "tradeoff", meta, SAME_SWEEP)
        earlier = [{"commit": earlier_meta.get("commit"), **r} for r in earlier]  # rows before rows had theirs
        for name, scene, rig, base, reference, view in _views_of_setups(scenes, size, base_config, skipped, quick,
                                                                         poses, pose_seed, views):
            swept = chosen_knobs(variants(scene, base, quick, repeat), knobs)
            with RendererPool(gl) as pool:
                r, _ = run_sweep(gl, scene, rig, reference, swept, ppd, repeat,
                                 progress, with_flip=True, pool=pool, measure_all=_measurer(cluster, name, rig, repeat),
                                 reference_spp=reference_spp, per_frame=reference_per_frame(quick))
            for row in r:
                row["scene"], row["view"], row["view_kind"], row["commit"] = name, view, view_kind(view), meta["commit"]
            rows += r
            measured.add((name, view))
            write_report(out_dir, "tradeoff", {"meta": {**meta, "partial": True},  # a cut run keeps its views
                                               "rows": _with_earlier(earlier, rows, measured, knobs)})
    meta["kept_views"] = _kept_views(earlier, measured)
    kept = _unmeasured(earlier, measured, knobs)
    meta["kept_knobs"] = sorted({r["knob"] for r in kept if (r.get("scene"), r["view"]) in measured})
    older = sorted({str(r["commit"]) for r in kept} - {str(meta["commit"])})
    if older:
        meta["kept_from"] = older
    result = {"meta": meta, "rows": kept + rows}
    write_report(out_dir, "tradeoff", result)
    plot_tradeoff(result["rows"], out_dir, meta)
    return result


SWEEP_POSES = 8  # tradeoff and budget: head poses (half content, half random) beside the fixed view, unless --poses
BUDGETS_MS = (1000.0 / 90, 1000.0 / 120)  # bench budget's frame budgets unless --budget-ms gives others: 90, 120 Hz


def run_budget(out_dir, budgets=BUDGETS_MS, size=(1440, 1600), scenes=("default", "sponza"), repeat=10,
               ppd=metrics.DEFAULT_PPD, base_config=None, backend=None, progress=True, quick=False, workers=None,
               address=None, connect_timeout=DEFAULT_CONNECT_TIMEOUT_S, grid=None, poses=0, pose_seed=POSE_SEED,
               reference_spp=None, rungs=None, views=None) -> dict:
    """For each scene and budget: the pick (frame-wide knobs of `grid` and the effect per
    material), its predicted and measured ms and error, the best render of the measured grid that
    fits (every point of `grid` with every material on one rung) and the pick's FLIP above it
    (the optimality gap; negative: the pick beats every render of the grid). Each pick is also
    written as the config that reproduces it. `workers`: the per-rung measurements spread over
    Ray workers; each pick is confirmed here. Each view's reference is run()'s (`reference_spp`),
    and its noise floor is in every row: errors below it are noise. `rungs`: the rung keys a
    material chooses from (quality/rungs.py; default the ladder's effects). `views`: only those
    (views_of's `only`). Views of the folder's earlier budget reports that this run does not
    measure stay (SAME_BUDGET)."""
    from ..quality.budget import pick_toml
    from ..quality.frame_budget import choose_frame_under_budget, grid_best, measure_candidates
    from ..quality.frame_knobs import DEFAULT_KNOBS
    from ..util.output import atomic_write_bytes, write_png
    from .report import device_meta, markdown, write_report

    grid = grid or [DEFAULT_KNOBS]
    rows, grid_rows, fixed_rows, option_rows, skipped, measured = [], [], [], [], {}, set()
    reference_spp = reference_spp or (QUICK_REFERENCE_SPP if quick else REFERENCE_SPP)
    with _bench_gl(out_dir, backend) as gl, _workers(workers, address, connect_timeout) as cluster:
        meta = {**device_meta(gl.info()), "bench": "budget", "per_eye_size": list(size), "repeat": repeat,
                "ppd": ppd, "skipped": skipped, "workers": workers or 0, "grid": [k.label for k in grid],
                "poses": poses, "pose_seed": pose_seed, "pose_scheme": POSE_SCHEME, "reference_spp": reference_spp,
                "rungs": list(rungs) if rungs else "the ladder's effects",
                "noise_floor": "mean FLIP of the reference's two halves (each half its samples, its own seed) "
                               "against each other: conservative, each half has half the reference's samples",
                "model": "per point of the frame-knob grid, per material: extra GPU ms of each effect over all-raster "
                         "and mean FLIP over its pixels vs the reference, measured with that point's knobs; the "
                         "whole-frame passes (denoise, quadtree, photon map, ...) paid once per frame as fixed-cost "
                         "groups (budget_fixed.json); total error = sum importance x coverage x error; exact "
                         "multiple-choice knapsack per point, the best point taken (rayvr.quality.frame_budget)"}
        earlier = {n: _earlier_views(out_dir, n, meta, SAME_BUDGET)
                   for n in ("budget", "budget_grid", "budget_fixed", "budget_options")}
        for name, scene, rig, base, reference, view in _views_of_setups(scenes, size, base_config, skipped, quick,
                                                                         poses, pose_seed, views):
            with RendererPool(gl) as pool:
                converged = measure_reference(gl, scene, rig, reference, reference_spp, reference_per_frame(quick),
                                              pool)
                floor = metrics.flip(*(h.image for h in converged.halves), ppd=ppd)
                ref = converged.measured
                candidates, refused = measure_candidates(gl, scene, rig, ref, base, ppd, grid, repeat=repeat,
                                                         progress=progress, pool=pool,
                                                         measure_all=_measurer(cluster, name, rig, repeat),
                                                         rungs=rungs)
                skipped.update({f"{name} {view}: {k}": why for k, why in refused.items()})
                picks = [choose_frame_under_budget(gl, scene, rig, b, base, ref, ppd, candidates, repeat, progress,
                                                   pool) for b in budgets]
            grid_rows += [{"scene": name, "view": view, "knobs": c.knobs.label, "effect": e, "gpu_ms": ms, "flip": flip}
                          for c in candidates for e, (ms, flip) in c.rungs.items()]
            fixed_rows += [{"scene": name, "view": view, "knobs": c.knobs.label, "pass": g.name, "cost_ms": g.cost_ms,
                            "effects": sorted(g.effects)} for c in candidates for g in c.fixed]
            option_rows += [{"scene": name, "view": view, "knobs": c.knobs.label, "base_ms": c.base_ms,
                             "material": m.name, "coverage": m.coverage, "importance": m.importance,
                             "effect": o.effect, "cost_ms": o.cost_ms, "error": o.error}
                            for c in candidates for m in c.materials for o in m.options]
            for b, pick in zip(budgets, picks):
                best = grid_best(candidates, b)
                rows.append({"scene": name, "view": view, "view_kind": view_kind(view), "reference_ms": ref.gpu_ms,
                             "reference_spp": converged.samples, "noise_floor": floor,
                             **{k: v for k, v in pick.items() if k not in ("config", "image", "knobs")},
                             "knobs": pick["knobs"].label, "grid_points": len(grid), "grid_best": best,
                             "optimality_gap": None if best is None else pick["measured_flip"] - best["flip"],
                             "solver_gap": None if best is None or pick["solver_flip"] is None
                             else pick["solver_flip"] - best["flip"],
                             # what the pick's frame shows (the reference's material ids, the pick's effects)
                             "effect_share": None if ref.material is None else
                             effect_share([ref.material], scene.material_names(), pick["config"])})
                stem = f"{out_dir}/budget_{name}{view_suffix(view)}_{b:.4g}ms"
                write_png(f"{stem}.png", pick["image"])
                atomic_write_bytes(f"{stem}.toml", pick_toml(scene, pick, pick["config"], size).encode())
            measured.add((name, view))
            write_report(out_dir, "budget", {"meta": {**meta, "partial": True},  # a cut run keeps its views
                                             "rows": _with_earlier(earlier["budget"], rows, measured)})
    meta["kept_views"] = _kept_views(earlier["budget"], measured)
    rows, grid_rows, fixed_rows, option_rows = (
        _with_earlier(earlier[n], r, measured) for n, r in (("budget", rows), ("budget_grid", grid_rows),
                                                            ("budget_fixed", fixed_rows), ("budget_options", option_rows)))
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "budget", result, md=budget_headline(rows, meta) + "\n" + markdown("budget", result))
    write_report(out_dir, "budget_grid", {"meta": meta, "rows": grid_rows})
    write_report(out_dir, "budget_fixed", {"meta": meta, "rows": fixed_rows})
    write_report(out_dir, "budget_options", {"meta": meta, "rows": option_rows},
                 md="# budget_options\n\nThe solver's table: per view, point of the knob grid and material, each "
                    "rung's extra GPU ms over the all-raster frame and mean FLIP over the material's pixels, with the "
                    "material's screen coverage and importance (budget_options.json; base_ms: the all-raster frame).\n")
    plot_budget(rows, grid_rows, out_dir, meta)
    return result


def budget_headline(rows: list[dict], meta: dict) -> str:
    """The answer first: per scene and budget, the worst view of the set (by the pick's mean FLIP
    and by its measured frame, named with its kind), then per view the best mean FLIP the pick
    reaches, within the budget or not on the measured frame, how far it is from the grid's best
    render, and what the pick's frame shows."""
    def num(v, fmt):
        return "-" if v is None else format(v, fmt)

    def budget(r):
        return f"{r['budget_ms']:.4g} ms ({1000 / r['budget_ms']:.0f} Hz)"

    lines = [f"# The best image within each budget ({meta.get('gl_renderer', '?')}, "
             f"2x{meta['per_eye_size'][0]}x{meta['per_eye_size'][1]})", ""]
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["scene"], round(r["budget_ms"], 6)), []).append(r)
    if any(len(g) > 1 for g in groups.values()):
        # the headline: the set's worst view, by the pick's error and by its measured frame
        lines += ["The worst view of each scene and budget (over the fixed view and the head poses measured):", "",
                  "| scene | budget | views | worst mean FLIP | its view | slowest measured ms | its view "
                  "| all within |",
                  "|---|---|---|---|---|---|---|---|"]
        for (scene, _), g in groups.items():
            bad, slow = max(g, key=lambda r: r["measured_flip"]), max(g, key=lambda r: r["measured_ms"])
            lines.append(f"| {scene} | {budget(g[0])} | {len(g)} | {bad['measured_flip']:.4f} | {view_label(bad)} | "
                         f"{slow['measured_ms']:.2f} | {view_label(slow)} | "
                         f"{'yes' if all(r['within_budget'] for r in g) else 'NO'} |")
        lines.append("")
    lines += ["| scene | view | budget | mean FLIP | measured ms | within | frame knobs | grid's best FLIP within "
              "| gap | solver's gap | noise floor | the pick's frame shows |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        best = r.get("grid_best") or {}
        lines.append(f"| {r['scene']} | {view_label(r)} | {budget(r)} | "
                     f"{r['measured_flip']:.4f} | {r['measured_ms']:.2f} | {'yes' if r['within_budget'] else 'NO'} | "
                     f"{r['knobs']}{' (the grid render)' if r.get('from_grid') else ''} | "
                     f"{num(best.get('flip'), '.4f')} | {num(r.get('optimality_gap'), '+.4f')} | "
                     f"{num(r.get('solver_gap'), '+.4f')} | {num(r.get('noise_floor'), '.4f')} | "
                     f"{share_text(r.get('effect_share'))} |")
    lines += ["", "view: the bench's fixed view or head pose I (content: gazing at a point of the scene's content; "
              "random: looking about; rayvr/bench/head_poses.py).",
              "the pick's frame shows: the share of the view's pixels (both eyes) whose material the pick gives each "
              "effect, background: pixels that hit nothing (the reference's material ids).",
              "gap: the pick's mean FLIP minus the best render of the measured grid (every point of the "
              "frame-knob grid with every material on one rung) that fits the budget; negative: the pick is better. "
              "solver's gap: the same for the best per-material pick the solver made (the pick is the grid's render "
              "where that measured better: '(the grid render)').",
              f"noise floor: the reference's two halves against each other ({meta.get('reference_spp', '?')} samples "
              "a pixel in all): an error or a gap this small is the reference's noise, not the pick's.", ""]
    return "\n".join(lines)


def plot_budget(rows: list[dict], grid_rows: list[dict], out_dir, meta: dict | None = None) -> list:
    """One picture per scene and view: the grid's renders as GPU ms vs mean FLIP with their Pareto front,
    each budget as a vertical line and its pick as a star. Needs matplotlib."""
    from pathlib import Path

    from .report import pareto_front

    plt = _pyplot()
    if plt is None:
        return []

    written = []
    for scene, view in dict.fromkeys((r["scene"], r["view"]) for r in grid_rows):
        mine = [r for r in grid_rows if (r["scene"], r["view"]) == (scene, view)]
        fig, ax = plt.subplots(figsize=(11, 5.5), dpi=110)
        points = list(dict.fromkeys(r["knobs"] for r in mine))
        for knobs, label in zip(points, grid_labels(points)):
            pts = [(r["gpu_ms"], r["flip"]) for r in mine if r["knobs"] == knobs]
            ax.scatter(*zip(*pts), s=18, alpha=0.8, label=label)
        front = [mine[i] for i in pareto_front([(r["gpu_ms"], r["flip"]) for r in mine])]
        ax.step([r["gpu_ms"] for r in front], [r["flip"] for r in front], where="post", color="k", lw=1,
                label="Pareto front of the grid")
        picks = [r for r in rows if (r["scene"], r["view"]) == (scene, view)]
        if picks and picks[0].get("noise_floor") is not None:
            ax.axhline(picks[0]["noise_floor"], color="grey", ls=":", lw=1,
                       label=f"noise floor (reference halves) {picks[0]['noise_floor']:.4f}")
        for r in picks:
            ax.axvline(r["budget_ms"], color="grey", lw=0.8, ls="--")
            ax.scatter([r["measured_ms"]], [r["measured_flip"]], marker="*", s=160, color="crimson", zorder=5)
            ax.annotate(f"pick at {r['budget_ms']:.3g} ms", (r["measured_ms"], r["measured_flip"]), fontsize=7,
                        xytext=(4, 4), textcoords="offset points")
        written.append(_save_speed_error(plt, fig, ax, f"{scene}, {view} view: the budget's picks (stars) against "
                                         f"every render of its grid", Path(out_dir) / f"budget_{scene}{view_suffix(view)}.png",
                                         meta))
    return written


def grid_labels(labels: list[str]) -> list[str]:
    """The grid points' labels without the knob=value words every one of them has (a legend of
    what differs, not eight copies of `msaa=1 scale=1 temporal=off camera=pinhole`)."""
    words = [label.split() for label in labels]
    common = set.intersection(*(set(w) for w in words)) if words else set()
    return [" ".join(x for x in w if x not in common) or label for w, label in zip(words, labels)]


def _pyplot():
    """matplotlib's pyplot without a display, or None without matplotlib (the plots are skipped)."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save_speed_error(plt, fig, ax, title: str, path, meta: dict | None = None):
    """A GPU-ms-against-FLIP picture's axes, title (with the run's device, date and commit) and
    legend, written to `path` (returned)."""
    from .report import provenance

    ax.set_xscale("log")
    ax.set_xlabel("GPU ms per stereo frame (timer queries)")
    ax.set_ylabel("mean FLIP vs the converged reference (lower is better)")
    ax.set_title(title + (f"\n{provenance(meta)}" if meta else ""), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the points, not on them
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


KNOB_MARKERS = "os^Dv"


def plot_tradeoff(rows: list[dict], out_dir, meta: dict | None = None) -> list:
    """One picture per scene and view: every variant as GPU ms vs mean FLIP, coloured by knob, the
    Pareto front over all of them (the settings worth choosing) and the noise floor (the
    reference's two halves against each other) as a dashed line. Needs matplotlib."""
    from pathlib import Path

    from .report import pareto_front

    plt = _pyplot()
    if plt is None:
        return []

    written = []
    for scene, view in dict.fromkeys((r["scene"], r.get("view", "fixed")) for r in rows):
        here = [r for r in rows if r["scene"] == scene and r.get("view", "fixed") == view
                and isinstance(r.get("flip"), (int, float))]
        floor = [r["flip"] for r in here if r["knob"] == "noise floor"]
        mine = [r for r in here if r["knob"] != "noise floor"]
        if not mine:
            continue
        fig, ax = plt.subplots(figsize=(11, 5.5), dpi=110)
        for i, knob in enumerate(dict.fromkeys(r["knob"] for r in mine)):
            pts = [(r["gpu_ms"], r["flip"]) for r in mine if r["knob"] == knob]
            # ten colours a marker: past ten knobs the marker tells them apart
            ax.scatter(*zip(*pts), s=22, label=knob, alpha=0.85, marker=KNOB_MARKERS[i // 10 % len(KNOB_MARKERS)])
        front = [mine[i] for i in pareto_front([(r["gpu_ms"], r["flip"]) for r in mine])]
        ax.step([r["gpu_ms"] for r in front], [r["flip"] for r in front], where="post", color="k", lw=1,
                label="Pareto front")
        for r in front:
            ax.annotate(r["label"], (r["gpu_ms"], r["flip"]), fontsize=6, xytext=(3, 3), textcoords="offset points")
        if floor:
            ax.axhline(floor[0], color="grey", ls="--", lw=1, label=f"noise floor (reference halves) {floor[0]:.4f}")
        written.append(_save_speed_error(plt, fig, ax, f"{scene}, {view} view: speed vs accuracy, every knob",
                                         Path(out_dir) / f"tradeoff_{scene}{view_suffix(view)}.png", meta))
    return written