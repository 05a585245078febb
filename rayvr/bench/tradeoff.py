"""`rayvr bench tradeoff` and `--budget-ms`: the price list of accuracy.

Every knob setting (a *variant*: a material config plus render settings plus a resolution
scale) is rendered on the same stereo rig; its cost is the median GPU time of the whole frame
(sum of the passes' timer queries) and its error is measured against the reference image (the
most accurate setting rayvr has, from `reference.py`) with mean FLIP at the headset's pixels
per degree, PSNR and SSIM, over the whole image and over the pixels the knob touches.

The budget mode estimates, per material, what each effect costs and how much error it leaves
(`per_material_options`), picks one effect per material with `budget.solve_budget`, and then
renders and measures the chosen assignment for real.
"""
from __future__ import annotations

import contextlib
import fnmatch
from dataclasses import dataclass, field

import numpy as np

from ..camera import StereoRig
from ..materials import EFFECTS, MaterialConfig, implemented_effects
from ..renderer import Renderer, RenderSettings
from . import budget as budget_mod
from . import metrics


def _compare_settings():
    """One RenderSettings for the reference and every variant, so only the knob differs: no
    ambient term (it stands in for indirect light, which only the reference would model), the
    ACES tonemapper users see."""
    from .reference import reference_settings

    return reference_settings(tonemapper="aces")


# The reference for GPU sweeps at 2x1440x1600: REFERENCE_QUALITY's 256 glossy samples x 256
# area samples per hit would take minutes a frame there; this converges to within the FLIP
# differences the knobs make (64 glossy directions, 16 light samples, 4 bounces).
BENCH_QUALITY = {"bounces": 4, "samples": 64, "area_samples": 16}


@dataclass
class Variant:
    knob: str  # what is varied ("effect", "bounces", "resolution_scale", ...)
    value: object
    config: MaterialConfig
    settings: RenderSettings = field(default_factory=lambda: COMPARE_SETTINGS)
    scale: float = 1.0  # render at scale x size, compare upscaled to full size
    touches: tuple = ()  # material names this variant changes (the error mask); () = whole image

    @property
    def label(self) -> str:
        return f"{self.knob}={self.value}"


COMPARE_SETTINGS = _compare_settings()


@dataclass
class Measured:
    gpu_ms: float
    image: np.ndarray  # uint8 HxWx3, both eyes side by side, full size
    material: np.ndarray  # uint32 HxW material index per pixel (same layout)


def config_with(base: MaterialConfig, default: str | None = None, materials: dict | None = None,
                params: dict | None = None) -> MaterialConfig:
    """A copy of `base` with another default effect, per-material effects and effect params."""
    cfg = MaterialConfig(default=default or base.default, params={k: dict(v) for k, v in base.params.items()},
                         by_name=dict(base.by_name), by_id=dict(base.by_id), importance_of=dict(base.importance_of),
                         source=f"{base.source} (variant)")
    for name, effect in (materials or {}).items():
        cfg.by_name[name] = (effect, {})
    for effect, values in (params or {}).items():
        cfg.params.setdefault(effect, {}).update(values)
        # Per-material parameters win over [params]: a swept value must reach those too.
        for table in (cfg.by_name, cfg.by_id):
            for key, (e, p) in table.items():
                if e == effect:
                    table[key] = (e, {**p, **values})
    return cfg


def config_for_assignment(base: MaterialConfig, scene, effects: dict) -> MaterialConfig:
    """A config giving each material (by index, so glob characters in names cannot misfire) the
    effect in `effects` (default `raster`), keeping the base config's parameters for it when the
    effect is the one the base gives it."""
    names = scene.material_names()
    by_id = {}
    for i, (name, a) in enumerate(zip(names, base.assign(names, warn=False))):
        e = effects.get(name, "raster")
        by_id[i] = (e, a.params if a.effect == e else base.effect_params(e))
    return MaterialConfig(default="raster", params={k: dict(v) for k, v in base.params.items()}, by_id=by_id,
                          source=f"{base.source} (assignment)")


class RendererPool:
    """One Renderer per (scene, settings), reused across variants: a variant only swaps the
    material config, so shaders compile and the BVH builds once per sweep, not per variant."""

    def __init__(self, gl):
        self.gl, self._renderers = gl, {}

    def get(self, scene, settings: RenderSettings, config: MaterialConfig) -> Renderer:
        key = (id(scene), repr(settings))
        r = self._renderers.get(key)
        if r is None:
            r = self._renderers[key] = Renderer(scene, config, gl=self.gl, settings=settings)
        else:
            r.set_materials(config)
        return r

    def release(self) -> None:
        for r in self._renderers.values():
            r.release()
        self._renderers.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def measure(gl, scene, rig: StereoRig, variant: Variant, repeat: int = 10, warmup: int = 3,
            pool: RendererPool | None = None) -> Measured:
    w, h = rig.size
    small = (max(1, round(w * variant.scale)), max(1, round(h * variant.scale)))
    own = pool is None
    pool = pool or RendererPool(gl)
    r = pool.get(scene, variant.settings, variant.config)
    try:
        sized = rig.with_size(small)
        r.warm_up(sized)
        rigs = [sized] * (warmup + repeat)
        totals, last = [], None
        for i, frame in enumerate(r.render_sequence(rigs, aux=("material",))):
            if i >= warmup:
                totals.append(sum(frame.timings.values()))
            last = frame
    finally:
        if own:
            pool.release()
    image = np.hstack([last.left.color, last.right.color])
    material = np.hstack([last.left.aux["material"], last.right.aux["material"]])
    if small != (w, h):
        from PIL import Image

        image = np.asarray(Image.fromarray(image).resize((2 * w, h), Image.BILINEAR))
        material = np.asarray(Image.fromarray(material.astype(np.int32)).resize((2 * w, h), Image.NEAREST)).astype(np.uint32)
    return Measured(float(np.median(totals)), image, material)


def material_mask(scene, material_map: np.ndarray, names) -> np.ndarray | None:
    if not names:
        return None
    index = [i for i, n in enumerate(scene.material_names()) if any(fnmatch.fnmatchcase(n, g) for g in names)]
    return np.isin(material_map, index)


def error_row(ref: Measured, test: Measured, scene, variant: Variant, ppd: float, with_flip: bool = True) -> dict:
    mask = material_mask(scene, ref.material, variant.touches)
    if mask is not None and not mask.any():
        mask = None
    which = ("flip", "psnr", "ssim") if with_flip else ("psnr", "ssim")
    return metrics.compare(ref.image, test.image, mask=mask, ppd=ppd, metrics=which)


# ------------------------------------------------------------------------------- the knobs


def variants(scene, base: MaterialConfig, quick: bool = False) -> list[Variant]:
    """Every knob rayvr has today, each swept along its range (effects not implemented yet are
    left out; they appear here as they land)."""
    out: list[Variant] = []
    effects = implemented_effects()
    for e in effects:  # the whole scene on one rung of the ladder
        out.append(Variant("effect", e, config_with(base, default=e, materials={n: e for n in base.by_name})))
    ranges = {
        "area_samples": [1, 4, 16] if quick else [1, 2, 4, 8, 16, 32],
        "bounces": [1, 2] if quick else [1, 2, 3, 4, 8],
        "samples": [1, 4] if quick else [1, 2, 4, 8, 16, 32],
    }
    for effect in effects:
        # Sweep a parameter where the effect is in use: the materials the config gives it, or
        # (when it gives it none) the whole scene.
        users = tuple(n for n, (e, _) in base.by_name.items() if e == effect)
        on = base if (users or base.default == effect) else config_with(base, default=effect)
        touched = () if on.default == effect else users
        for param, values in ranges.items():
            if param in EFFECTS[effect].params:
                for v in values:
                    out.append(Variant(f"{effect}.{param}", v, config_with(on, params={effect: {param: v}}),
                                       touches=touched))
    for s in ([0.5, 1.0] if quick else [0.5, 0.75, 1.0]):
        out.append(Variant("resolution_scale", s, base, scale=s))
    return out


def run_sweep(gl, scene, rig, reference: Variant, variants_: list[Variant], ppd: float, repeat=10,
              progress=True, with_flip=True, pool: RendererPool | None = None) -> tuple[list[dict], Measured]:
    ref = measure(gl, scene, rig, reference, repeat, pool=pool)
    rows = []
    iterator = variants_
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(variants_), unit="variant", desc=f"tradeoff {scene.name}")
    for v in iterator:
        m = measure(gl, scene, rig, v, repeat, pool=pool)
        rows.append({"scene": scene.name, "knob": v.knob, "value": v.value, "label": v.label,
                     "gpu_ms": m.gpu_ms, **error_row(ref, m, scene, v, ppd, with_flip),
                     "reference_ms": ref.gpu_ms})
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return rows, ref


# ------------------------------------------------------------------------------- budget


def per_material_options(gl, scene, rig, reference_image: Measured, base: MaterialConfig, ppd: float,
                         effects=None, repeat=10, min_coverage=1e-4, progress=True, pool=None):
    """Per material and effect: extra GPU ms over all-`raster` and the error left on its pixels.

    One render per effect (the whole scene on that rung) instead of one per material and
    effect: a material's error is the mean FLIP over its own pixels in that render, and the
    effect's extra cost is shared out over materials in proportion to their pixels (the traced
    passes run over compacted pixel lists, so their cost follows pixel counts). Both are
    approximations: reflections also show other materials, and dispatch overheads are shared;
    the chosen assignment is therefore rendered and measured for real afterwards.
    Materials covering < min_coverage of the image stay `raster`."""
    effects = list(effects or implemented_effects())
    names = scene.material_names()
    ids = reference_image.material
    coverage = np.bincount(np.where(ids < len(names), ids, len(names)).ravel(),
                           minlength=len(names) + 1)[:len(names)] / ids.size
    importance = [a.importance for a in base.assign(names, warn=False)]
    covered = [i for i in range(len(names)) if coverage[i] >= min_coverage]
    flip_maps, extra_ms, raster_ms = {}, {}, None
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(effects), unit="effect", desc=f"budget {scene.name}")
    for e in effects:
        cfg = config_for_assignment(base, scene, {n: e for n in names})
        m = measure(gl, scene, rig, Variant("budget", e, cfg), repeat, pool=pool)
        flip_maps[e] = metrics.flip_map(reference_image.image, m.image, ppd=ppd)
        extra_ms[e] = m.gpu_ms
        if e == "raster":
            raster_ms = m.gpu_ms
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    if raster_ms is None:
        raise ValueError("the budget model needs 'raster' among the effects (it is the cost baseline)")
    share = coverage / max(coverage[covered].sum(), 1e-12)
    options = []
    for i in covered:
        mask = ids == i
        opts = [budget_mod.Option(e, max(extra_ms[e] - raster_ms, 0.0) * share[i], float(flip_maps[e][mask].mean()))
                for e in effects]
        options.append(budget_mod.MaterialOptions(names[i], opts, importance=importance[i], coverage=float(coverage[i])))
    return raster_ms, options


BUDGET_TOLERANCE = 1.02  # measured frames within 2 % of the budget count as within (timer noise)
BUDGET_ROUNDS = 4


def choose_under_budget(gl, scene, rig, budget_ms: float, base: MaterialConfig, reference_image: Measured,
                        ppd: float, repeat=10, progress=True, pool=None, options=None) -> dict:
    """Pick effects per material for `budget_ms`, render the pick and measure it.

    The per-material costs are estimates (a traced effect also has fixed costs, classify and
    dispatch, that come with its first material); when the measured frame overshoots, the chosen
    options' costs are scaled by measured/predicted and the choice is solved again, at most
    BUDGET_ROUNDS times. If no round fits, the best measured pick that did fit is returned, else
    the cheapest assignment. `options`: (base_ms, per-material options) measured already, to
    solve several budgets from one measurement."""
    base_ms, options = options or per_material_options(gl, scene, rig, reference_image, base, ppd, repeat=repeat,
                                                       progress=progress, pool=pool)

    def attempt(opts, budget):
        result = budget_mod.solve_budget(opts, budget, base_ms=base_ms)
        cfg = config_for_assignment(base, scene, result.assignment)
        chosen = measure(gl, scene, rig, Variant("budget", budget_ms, cfg), repeat, pool=pool)
        return {"budget_ms": budget_ms, "predicted_ms": result.total_ms, "measured_ms": chosen.gpu_ms,
                "within_budget": chosen.gpu_ms <= budget_ms * BUDGET_TOLERANCE, "feasible": result.feasible,
                "predicted_error": result.error, "measured_flip": metrics.flip(reference_image.image, chosen.image, ppd=ppd),
                "assignment": result.assignment, "config": cfg, "image": chosen.image}

    scale: dict = {}
    tried = []
    for _ in range(BUDGET_ROUNDS):
        adjusted = [budget_mod.MaterialOptions(
            o.name, [budget_mod.Option(x.effect, x.cost_ms * scale.get((o.name, x.effect), 1.0), x.error)
                     for x in o.options], importance=o.importance, coverage=o.coverage) for o in options]
        pick = attempt(adjusted, budget_ms)
        tried.append(pick)
        predicted_extra, measured_extra = pick["predicted_ms"] - base_ms, pick["measured_ms"] - base_ms
        if pick["within_budget"] or not pick["feasible"] or predicted_extra <= 0:
            break
        factor = measured_extra / predicted_extra
        for name, effect in pick["assignment"].items():
            if effect != "raster":
                scale[(name, effect)] = scale.get((name, effect), 1.0) * max(factor, 1.0)
    fitting = [p for p in tried if p["within_budget"]]
    if fitting:
        best = min(fitting, key=lambda p: p["measured_flip"])
    elif tried[-1]["feasible"]:
        best = attempt(options, 0.0)  # the cheapest assignment: nothing cheaper exists
        tried.append(best)
    else:
        best = tried[-1]
    return {**best, "rounds": len(tried)}


# ------------------------------------------------------------------------------- entry points


def _setups(names, size, base_config, skipped, quick=False):
    """(name, scene, rig, base config, reference variant) per available benchmark scene."""
    from ..materials import load_config
    from .reference import reference_config
    from .scenes import bench_scenes

    for name, scene, rig in bench_scenes(names, size, skipped):
        base = load_config(base_config(name) if base_config else None)
        ref = reference_config(scene, quick=quick, quality=None if quick else BENCH_QUALITY)
        yield name, scene, rig, base, Variant("reference", "reference", ref, COMPARE_SETTINGS)


@contextlib.contextmanager
def _bench_gl(out_dir, backend):
    """Check the output folder first (fail before any work), then a GL context for the run."""
    from ..context import create_context
    from ..output import ensure_writable_dir

    ensure_writable_dir(out_dir)
    gl = create_context(backend)
    try:
        yield gl
    finally:
        gl.release()


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=10, quick=False, ppd=metrics.DEFAULT_PPD,
        base_config=None, backend=None, progress=True) -> dict:
    """Sweep every knob on each scene against its reference; write tradeoff.json/.md and plots."""
    from .report import device_meta, write_report

    rows, skipped = [], {}
    with _bench_gl(out_dir, backend) as gl:
        for name, scene, rig, base, reference in _setups(scenes, size, base_config, skipped, quick):
            with RendererPool(gl) as pool:
                r, _ = run_sweep(gl, scene, rig, reference, variants(scene, base, quick), ppd, repeat, progress,
                                 with_flip=True, pool=pool)
            for row in r:
                row["scene"] = name
            rows += r
        meta = {**device_meta(gl.info()), "bench": "tradeoff", "per_eye_size": list(size), "repeat": repeat,
                "ppd": ppd, "skipped": skipped, "error": "vs the scene's reference (rayvr.bench.reference); "
                "flip/psnr/ssim over both eyes side by side; *_mask over the pixels the knob touches"}
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "tradeoff", result)
    plot_tradeoff(rows, out_dir)
    return result


def run_budget(out_dir, budgets=(4.0, 8.0), size=(1440, 1600), scenes=("default", "sponza"), repeat=10,
               ppd=metrics.DEFAULT_PPD, base_config=None, backend=None, progress=True, quick=False) -> dict:
    """For each budget: the chosen effect per material, its predicted and measured ms and error."""
    from ..output import write_png
    from .report import device_meta, write_report

    rows, skipped = [], {}
    with _bench_gl(out_dir, backend) as gl:
        for name, scene, rig, base, reference in _setups(scenes, size, base_config, skipped, quick):
            with RendererPool(gl) as pool:
                ref = measure(gl, scene, rig, reference, repeat, pool=pool)
                options = per_material_options(gl, scene, rig, ref, base, ppd, repeat=repeat, progress=progress,
                                               pool=pool)
                picks = [choose_under_budget(gl, scene, rig, b, base, ref, ppd, repeat, progress, pool, options)
                         for b in budgets]
            for b, pick in zip(budgets, picks):
                rows.append({"scene": name, "reference_ms": ref.gpu_ms,
                             **{k: v for k, v in pick.items() if k not in ("config", "image")}})
                write_png(f"{out_dir}/budget_{name}_{b:g}ms.png", pick["image"])
        meta = {**device_meta(gl.info()), "bench": "budget", "per_eye_size": list(size), "repeat": repeat,
                "ppd": ppd, "skipped": skipped,
                "model": "per material: extra GPU ms of each effect over all-raster and mean FLIP over its "
                         "pixels vs the reference; total error = sum importance x coverage x error; exact "
                         "multiple-choice knapsack (rayvr.bench.budget)"}
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "budget", result)
    return result


def auto_config(renderer, rig: StereoRig, budget_ms: float, ppd: float = metrics.DEFAULT_PPD, repeat: int = 5,
                progress: bool = True) -> tuple[MaterialConfig, dict]:
    """`--budget-ms` for capture and preview: effects per material of `renderer.scene` that keep the
    frame within `budget_ms` on this device with the least error, starting from the renderer's
    current config. Returns the config and the summary (predicted and measured ms and FLIP)."""
    from .reference import reference_config

    gl, scene = renderer.gl, renderer.scene
    reference = Variant("reference", "reference",
                        reference_config(scene, quick=gl.is_software, quality=None if gl.is_software else BENCH_QUALITY))
    with RendererPool(gl) as pool:
        ref = measure(gl, scene, rig, reference, repeat=1, warmup=1, pool=pool)
        pick = choose_under_budget(gl, scene, rig, budget_ms, renderer.config, ref, ppd, repeat, progress, pool)
    summary = {k: v for k, v in pick.items() if k not in ("config", "image")}
    return pick["config"], summary


def describe_pick(summary: dict) -> str:
    """A few lines for the terminal or the HUD."""
    state = ("within" if summary["within_budget"] else "OVER") + ("" if summary["feasible"] else " (cheapest assignment)")
    lines = [f"budget {summary['budget_ms']:g} ms: {state}; predicted {summary['predicted_ms']:.2f} ms, "
             f"measured {summary['measured_ms']:.2f} ms, mean FLIP {summary['measured_flip']:.4f}"]
    by_effect: dict = {}
    for name, effect in summary["assignment"].items():
        by_effect.setdefault(effect, []).append(name)
    lines += [f"  {e:12s} {', '.join(sorted(n))}" for e, n in sorted(by_effect.items())]
    return "\n".join(lines)


def plot_tradeoff(rows: list[dict], out_dir) -> list:
    """One picture per scene: every variant as GPU ms vs mean FLIP, coloured by knob, with the
    Pareto front over all of them (the settings worth choosing). Needs matplotlib."""
    from pathlib import Path

    try:
        import matplotlib
    except ImportError:
        return []
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .report import pareto_front

    written = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene and isinstance(r.get("flip"), (int, float))]
        fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
        for knob in dict.fromkeys(r["knob"] for r in mine):
            pts = [(r["gpu_ms"], r["flip"]) for r in mine if r["knob"] == knob]
            ax.scatter(*zip(*pts), s=22, label=knob, alpha=0.85)
        front = [mine[i] for i in pareto_front([(r["gpu_ms"], r["flip"]) for r in mine])]
        ax.step([r["gpu_ms"] for r in front], [r["flip"] for r in front], where="post", color="k", lw=1,
                label="Pareto front")
        for r in front:
            ax.annotate(r["label"], (r["gpu_ms"], r["flip"]), fontsize=6, xytext=(3, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_xlabel("GPU ms per stereo frame (timer queries)")
        ax.set_ylabel("mean FLIP vs reference (lower is better)")
        ax.set_title(f"{scene}: speed vs accuracy, every knob", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        path = Path(out_dir) / f"tradeoff_{scene}.png"
        fig.savefig(path)
        plt.close(fig)
        written.append(path)
    return written
