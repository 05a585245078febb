"""Automatic per-material effects under a frame budget (`--budget-ms`, `rayvr bench budget`).

Model
-----
Each material ``m`` offers options ``o`` (an effect on the ladder, e.g. ``raster``, ``ssr``,
``rt1``), each with a measured GPU cost ``cost_ms[m, o]`` and a measured error ``error[m, o]``.
The frame costs::

    total_ms = base_ms + sum_m cost_ms[m, o_m]

(``base_ms`` is everything that does not depend on the choice: G-buffer, tonemap, ...) and its
error is::

    total_error = sum_m importance_m * coverage_m * error[m, o_m]

``error`` is meant as the mean error (e.g. mean FLIP) over the pixels of that material, and
``coverage`` as the fraction of the screen those pixels cover, so ``coverage * error`` is the
material's share of the whole-image mean error; coverage already falls with distance, which is
how distance enters. Leave coverage at 1 if your errors are already whole-image contributions.
``importance`` (default 1) is the user's weight from the scene config.

We pick one option per material minimising ``total_error`` subject to ``total_ms <= budget_ms``:
a multiple-choice knapsack. Per-pixel costs are additive (a traced pass runs over a compacted list
of its materials' pixels). Some passes are not per pixel: the denoiser filters the whole image
once any material takes an effect it filters, the screen-space quadtree is built once for every
`ssr` material, `classify` lists the traced pixels once. Those are ``FixedCost`` groups: the
frame pays a group's ``cost_ms`` once when any material takes one of its effects::

    total_ms = base_ms + sum_g [g used] * fixed_g + sum_m cost_ms[m, o_m]

Without them a frame that puts two small materials on `path` is predicted to cost two slivers of
the whole-scene `path` render and measures a whole denoiser more (Sponza at 2x1440x1600 on the
GPU: 3.5 ms of an 11.1 ms budget; docs/budget.md).

Solver
------
Exact, on the real (not rounded) costs. With fixed-cost groups, every subset T of the groups (but
those charging a group whose effects the groups left out ban: _useful_subsets) is solved as a
plain knapsack over the options whose groups lie in T, with T's fixed costs taken from
the budget; the least error over all T is the optimum (an assignment using groups U is solved
exactly under T = U and charged too much under any larger T). The plain knapsack is dynamic
programming over materials that keeps, after each material, only the Pareto-optimal partial
assignments (no other partial one is both cheaper and lower-error) and drops those that cannot
fit even with the cheapest options for the remaining materials. The optimum is an extension of
a Pareto-optimal prefix, so nothing optimal is lost. The fronts stay small in practice (hundreds
to a few thousand points for 50 materials x 7 effects), and each step is a handful of numpy sorts.

If even the cheapest assignment exceeds the budget, the cheapest one (ties broken by error) is
returned with ``feasible=False`` instead of raising.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import metrics
from ..frame.effects import implemented_effects
from .frame_knobs import DEFAULT_KNOBS
from .measure import COMPARE_SETTINGS, camera_refusal, config_for_assignment, local_measurer, measure
from .metric_pool import judge

# Slack for floating-point sums when comparing against the budget (1 ns in ms units).
COST_EPS_MS = 1e-6


@dataclass(frozen=True)
class Option:
    """One effect a material can use, with its measured cost (ms) and error."""

    effect: str
    cost_ms: float
    error: float


@dataclass(frozen=True)
class FixedCost:
    """A pass the frame runs once when any material takes one of `effects`, whatever its pixels."""

    name: str  # the pass (e.g. "denoise")
    cost_ms: float
    effects: frozenset


@dataclass
class MaterialOptions:
    """The options of one material plus its weights (see the module docstring)."""

    name: str
    options: list[Option]
    importance: float = 1.0
    coverage: float = 1.0

    @property
    def weight(self) -> float:
        return self.importance * self.coverage


@dataclass
class BudgetResult:
    """The chosen assignment and what it costs.

    ``choice[i]`` indexes ``materials[i].options``; ``assignment`` maps material name to effect.
    ``error`` is the weighted total error; ``feasible`` is False when nothing fits the budget
    (then the cheapest assignment is returned).
    """

    budget_ms: float
    base_ms: float
    total_ms: float
    error: float
    feasible: bool
    choice: list[int]
    assignment: dict[str, str]
    materials: list[MaterialOptions] = field(repr=False)
    fixed_ms: float = 0.0  # the fixed-cost groups' part of total_ms
    fixed: tuple = ()  # their names

    def rows(self) -> list[dict]:
        """One row per material (for `report.write_report`)."""
        out = []
        for m, i in zip(self.materials, self.choice):
            o = m.options[i]
            out.append({
                "material": m.name,
                "effect": o.effect,
                "cost_ms": o.cost_ms,
                "error": o.error,
                "importance": m.importance,
                "coverage": m.coverage,
                "weighted_error": m.weight * o.error,
            })
        return out

    def summary(self) -> dict:
        return {
            "budget_ms": self.budget_ms,
            "base_ms": self.base_ms,
            "total_ms": self.total_ms,
            "error": self.error,
            "feasible": self.feasible,
            "fixed_ms": self.fixed_ms,
            "fixed": list(self.fixed),
        }


def _finite(x, what: str, nonneg: bool = True) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be a number, got {x!r}") from None
    if not math.isfinite(v) or (nonneg and v < 0):
        raise ValueError(f"{what} must be a finite{' non-negative' if nonneg else ''} number, got {x!r}")
    return v


def _as_option(o, where: str) -> Option:
    if isinstance(o, Option):
        effect, cost, err = o.effect, o.cost_ms, o.error
    elif isinstance(o, dict):
        try:
            effect, cost, err = o["effect"], o["cost_ms"], o["error"]
        except KeyError as e:
            raise ValueError(f"{where}: option dict needs 'effect', 'cost_ms', 'error' (missing {e})") from None
    else:
        try:
            effect, cost, err = o
        except (TypeError, ValueError):
            raise TypeError(f"{where}: an option is (effect, cost_ms, error), got {o!r}") from None
    return Option(str(effect), _finite(cost, f"{where} {effect!r} cost_ms"),
                  _finite(err, f"{where} {effect!r} error", nonneg=False))


def as_materials(materials) -> list[MaterialOptions]:
    """Normalise input: `MaterialOptions`, or dicts with ``name``, ``options`` (a list of
    `Option`, ``(effect, cost_ms, error)`` tuples or dicts) and optional ``importance`` and
    ``coverage``. Validates numbers and unique names."""
    out: list[MaterialOptions] = []
    seen = set()
    for k, m in enumerate(materials):
        if isinstance(m, MaterialOptions):
            name, opts, imp, cov = m.name, m.options, m.importance, m.coverage
        elif isinstance(m, dict):
            if "name" not in m or "options" not in m:
                raise ValueError(f"material #{k} needs 'name' and 'options'")
            name, opts = m["name"], m["options"]
            imp, cov = m.get("importance", 1.0), m.get("coverage", 1.0)
        else:
            raise TypeError(f"material #{k} must be a MaterialOptions or dict, got {type(m).__name__}")
        name = str(name)
        if name in seen:
            raise ValueError(f"material name {name!r} appears twice")
        seen.add(name)
        opts = [_as_option(o, f"material {name!r}") for o in opts]
        if not opts:
            raise ValueError(f"material {name!r} has no options")
        out.append(MaterialOptions(name, opts, _finite(imp, f"material {name!r} importance"),
                                   _finite(cov, f"material {name!r} coverage")))
    return out


def _pareto(cost: np.ndarray, err: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats on both cost and error (one per tie)."""
    order = np.lexsort((err, cost))  # by cost, then error
    e = err[order]
    best_before = np.minimum.accumulate(np.concatenate(([np.inf], e[:-1])))
    return order[e < best_before]


def solve_budget(materials, budget_ms: float, base_ms: float = 0.0, fixed=()) -> BudgetResult:
    """Choose one option per material minimising weighted error with total ms <= budget_ms.

    See the module docstring for the model; `fixed`: FixedCost groups. Exact; ``feasible=False``
    (with the cheapest assignment) when even that exceeds the budget.
    """
    mats = as_materials(materials)
    budget_ms = _finite(budget_ms, "budget_ms", nonneg=False)
    base_ms = _finite(base_ms, "base_ms")
    groups = [g for g in fixed if _finite(g.cost_ms, f"fixed cost {g.name!r}") > 0]
    best = None
    for charged in _useful_subsets(groups):
        banned = set().union(*(g.effects for g in groups if g not in charged))
        kept = [[i for i, o in enumerate(m.options) if o.effect not in banned] for m in mats]
        if not all(kept):
            continue  # a material with only charged-elsewhere effects: no assignment under this subset
        sub = [MaterialOptions(m.name, [m.options[i] for i in idx], m.importance, m.coverage)
               for m, idx in zip(mats, kept)]
        fixed_ms = sum(g.cost_ms for g in charged)
        r = _solve_plain(sub, budget_ms, base_ms + fixed_ms)
        r = BudgetResult(budget_ms, base_ms, r.total_ms, r.error, r.feasible,
                         [idx[i] for idx, i in zip(kept, r.choice)], r.assignment, mats,
                         fixed_ms, tuple(g.name for g in charged))
        if best is None or _better(r, best):
            best = r
    if best is None:
        raise ValueError("no assignment avoids every fixed-cost group: give each material an option outside them")
    return best


def _useful_subsets(groups: list[FixedCost]):
    """The subsets of `groups` worth solving under: every subset but those charging a group whose
    effects the groups left out ban already (it is paid for nothing). A pass's layers (fixed_costs)
    nest, so leaving out its first layer prunes all the others: the count stays near the product of
    the passes' layer counts, not 2 ** len(groups)."""
    order = sorted(groups, key=lambda g: -len(g.effects))  # wider first: leaving one out bans the most

    def walk(i, charged, banned):
        if i == len(order):
            yield tuple(g for g in groups if g in charged)
            return
        g = order[i]
        if not g.effects <= banned:
            yield from walk(i + 1, charged | {g}, banned)
        yield from walk(i + 1, charged, banned | g.effects)

    yield from walk(0, frozenset(), frozenset())


def _better(a: BudgetResult, b: BudgetResult) -> bool:
    """Feasible before infeasible; then less error (feasible) or less cost (infeasible)."""
    if a.feasible != b.feasible:
        return a.feasible
    return (a.error, a.total_ms) < (b.error, b.total_ms) if a.feasible else (a.total_ms, a.error) < (b.total_ms, b.error)


def _solve_plain(mats: list[MaterialOptions], budget_ms: float, base_ms: float) -> BudgetResult:
    """The knapsack without fixed costs (the module docstring's dynamic programming)."""
    costs = [np.array([o.cost_ms for o in m.options]) for m in mats]
    errs = [m.weight * np.array([o.error for o in m.options]) for m in mats]

    # Cheapest assignment (lowest error among equally cheap options): the fallback, and a bound.
    cheapest = [int(np.lexsort((e, c))[0]) for c, e in zip(costs, errs)]
    min_cost = np.array([c[i] for c, i in zip(costs, cheapest)])
    # rest[k]: the least any assignment of materials k.. can cost.
    rest = np.concatenate((np.cumsum(min_cost[::-1])[::-1], [0.0]))
    limit = budget_ms + COST_EPS_MS

    if base_ms + rest[0] > limit:
        return _result(mats, cheapest, budget_ms, base_ms, costs, errs, feasible=False)

    # Front after k materials: partial costs/errors, plus for back-tracking the index into the
    # previous front and the option chosen.
    f_cost = np.array([base_ms])
    f_err = np.array([0.0])
    parents: list[np.ndarray] = []
    picks: list[np.ndarray] = []
    for k, (c, e) in enumerate(zip(costs, errs)):
        n_opt = len(c)
        cand_cost = (f_cost[:, None] + c[None, :]).ravel()
        cand_err = (f_err[:, None] + e[None, :]).ravel()
        # Keep only prefixes that can still be completed within the budget.
        ok = np.flatnonzero(cand_cost + rest[k + 1] <= limit)
        keep = ok[_pareto(cand_cost[ok], cand_err[ok])]
        f_cost, f_err = cand_cost[keep], cand_err[keep]
        parents.append(keep // n_opt)
        picks.append(keep % n_opt)

    best = int(np.argmin(f_err))
    choice = [0] * len(mats)
    for k in range(len(mats) - 1, -1, -1):
        choice[k] = int(picks[k][best])
        best = int(parents[k][best])
    return _result(mats, choice, budget_ms, base_ms, costs, errs, feasible=True)


def _result(mats, choice, budget_ms, base_ms, costs, errs, feasible) -> BudgetResult:
    total = base_ms + sum(float(c[i]) for c, i in zip(costs, choice))
    error = sum(float(e[i]) for e, i in zip(errs, choice))
    return BudgetResult(
        budget_ms=budget_ms,
        base_ms=base_ms,
        total_ms=total,
        error=error,
        feasible=feasible,
        choice=list(choice),
        assignment={m.name: m.options[i].effect for m, i in zip(mats, choice)},
        materials=mats,
    )


# --------------------------------------------------------- measured options, then solved

def per_material_options(gl, scene, rig, reference_image, base, ppd: float,
                         effects=None, repeat=10, min_coverage=1e-4, progress=True, pool=None, measure_all=None,
                         knobs=None):
    """Per material and effect: extra GPU ms over all-`raster` and the error left on its pixels.

    One render per effect (the whole scene on that rung) instead of one per material and
    effect: a material's error is the mean FLIP over its own pixels in that render, and the
    effect's extra cost is shared out over materials in proportion to their pixels (the traced
    passes run over compacted pixel lists, so their cost follows pixel counts). Both are
    approximations: reflections also show other materials, and dispatch overheads are shared;
    the chosen assignment is therefore rendered and measured for real afterwards.
    Materials covering < min_coverage of the image stay `raster`. `measure_all`: how the
    per-effect renders are measured (measure.local_measurer by default; cluster.sweep_measurer: Ray workers).
    `knobs`: the frame-wide knobs every render has (quality/frame_knobs.py; None: the defaults)."""
    rungs = measure_rungs(gl, scene, rig, reference_image, base, ppd, effects, repeat, progress, pool, measure_all, knobs)
    return options_from_rungs(scene, reference_image, base, rungs, min_coverage)


def measure_rungs(gl, scene, rig, reference_image, base, ppd: float, effects=None, repeat=10, progress=True,
                  pool=None, measure_all=None, knobs=None) -> dict:
    """{rung: (GPU ms, FLIP map against the reference, {pass: GPU ms})} of the whole scene on each rung (`effects`:
    rung keys, quality/rungs.py; default every effect of the ladder); a rung the camera cannot
    render (screen-space tracing through a camera that is not a pinhole) is left out, so no
    material takes it under these knobs."""
    knobs = knobs or DEFAULT_KNOBS
    names = scene.material_names()
    renders = [(e, knobs.variant("budget", e, config_for_assignment(base, scene, {n: e for n in names}),
                                 COMPARE_SETTINGS)) for e in effects or implemented_effects()]
    renders = [(e, v) for e, v in renders if not camera_refusal(v, names, rig)]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(renders), unit="effect", desc=f"budget {scene.name} {knobs.label}")
    measure_all = measure_all or local_measurer(gl, scene, rig, repeat, pool)
    try:
        # each rung's FLIP map made in another process while the next one renders
        pending = [(e, m.gpu_ms, judge(metrics.flip_map, reference_image.image, m.image, ppd), m.passes)
                   for (e, _), m in zip(renders, measure_all([v for _, v in renders], bar))]
        return {e: (ms, flip.result(), passes) for e, ms, flip, passes in pending}
    finally:
        if bar is not None:
            bar.close()


# A pass grows into a fixed cost by more than this over the all-raster frame, plus FIXED_COST_NOISE
# of its own time there (a pass both run, e.g. tonemap, jitters with its length): less is timer noise.
FIXED_COST_MIN_MS = 0.05
FIXED_COST_NOISE = 0.1


def fixed_costs(rungs: dict) -> tuple[list[FixedCost], dict]:
    """The fixed-cost groups in measure_rungs' renders and each rung's extra ms left per pixel.

    A traced effect's own passes (`rt_*`) run over its pixels' list: per pixel. Every other pass
    that a rung's render adds or grows over the all-raster render (denoise, quadtree, classify,
    second_layer, ...) runs over the whole frame once, and a frame pays for it what the costliest of
    its rungs grows it by. So a pass is layers: the first costs the least growth and comes with
    every rung that grows it, each next one the step to the next costlier rungs and comes with
    those; a frame pays the layers of the costliest rung it takes, and each whole-scene render is
    predicted exactly. Rungs within timer noise of each other share a layer (at their most; the
    others pay the difference out of their per-pixel share). A pass that shrinks (shade, which
    skips traced pixels) stays per pixel."""
    raster = rungs["raster"][2] if len(rungs["raster"]) > 2 else {}
    grown: dict = {}
    per_pixel = {}
    for e, (ms, _, *passes) in rungs.items():
        extra = max(ms - rungs["raster"][0], 0.0)
        for p, t in (passes[0] if passes else {}).items():
            delta = t - raster.get(p, 0.0)
            noise = FIXED_COST_MIN_MS + FIXED_COST_NOISE * raster.get(p, 0.0)
            if e != "raster" and not p.startswith("rt_") and delta > noise:
                grown.setdefault(p, {})[e] = delta
                extra -= delta
        per_pixel[e] = max(extra, 0.0)
    layers: dict = {}  # frozenset of rungs -> (pass layer names, ms)
    for p, by in sorted(grown.items()):
        below, levels = 0.0, _growth_levels(by)
        for k, (top, members) in enumerate(levels):
            for e in members:  # a rung charged its level's top pays the rest out of its own per-pixel share
                per_pixel[e] = max(per_pixel[e] - (top - by[e]), 0.0)
            # this level's rungs and the costlier ones; passes the same rungs run are one group
            # (photon's map: trace, sort, scan, cells), so the solver's subsets of groups stay few
            effects = frozenset(e for _, costlier in levels[k:] for e in costlier)
            names, cost = layers.get(effects, ((), 0.0))
            layers[effects] = (names + (p if k == 0 else f"{p}+{k}",), cost + top - below)
            below = top
    return [FixedCost("+".join(names), cost, effects) for effects, (names, cost) in layers.items()], per_pixel


def _growth_levels(by: dict) -> list[tuple[float, list]]:
    """A pass's growth by rung {rung: ms} as levels, cheapest first: (the level's ms, its rungs),
    rungs within FIXED_COST_MIN_MS + FIXED_COST_NOISE x the level's ms of its costliest in one."""
    order = sorted(by, key=by.get, reverse=True)
    levels = []
    while order:
        top = by[order[0]]
        members = [e for e in order if by[e] >= top - (FIXED_COST_MIN_MS + FIXED_COST_NOISE * top)]
        levels.append((top, members))
        order = order[len(members):]
    return levels[::-1]


def options_from_rungs(scene, reference_image, base, rungs: dict, min_coverage=1e-4):
    """(the all-`raster` frame's ms, per-material options, fixed-cost groups) from measure_rungs'
    renders: a rung's per-pixel extra ms shared out over materials by their pixels."""
    if "raster" not in rungs:
        raise ValueError("the budget model needs 'raster' among the effects (it is the cost baseline)")
    names = scene.material_names()
    ids = reference_image.material
    coverage = np.bincount(np.where(ids < len(names), ids, len(names)).ravel(),
                           minlength=len(names) + 1)[:len(names)] / ids.size
    importance = [a.importance for a in base.assign(names, warn=False)]
    covered = [i for i in range(len(names)) if coverage[i] >= min_coverage]
    fixed, per_pixel = fixed_costs(rungs)
    share = coverage / max(coverage[covered].sum(), 1e-12)
    options = []
    for i in covered:
        mask = ids == i
        opts = [Option(e, per_pixel[e] * share[i], float(r[1][mask].mean())) for e, r in rungs.items()]
        options.append(MaterialOptions(names[i], opts, importance=importance[i], coverage=float(coverage[i])))
    return rungs["raster"][0], options, fixed


BUDGET_TOLERANCE = 1.02  # measured frames within 2 % of the budget count as within (timer noise)
BUDGET_SLACK = 0.85  # a pick measured below this share of its budget is solved again with its costs scaled down
MIN_COST_SCALE = 0.25  # the most one round scales an effect's estimated cost down
BUDGET_ROUNDS = 6


def measure_assignment(gl, scene, rig, budget_ms: float, base, reference_image, ppd: float, assignment: dict,
                       repeat=10, pool=None, knobs=None) -> dict:
    """Render {material: effect} (the others `raster`) with `knobs` and measure it against `budget_ms`."""
    cfg = config_for_assignment(base, scene, assignment)
    chosen = measure(gl, scene, rig, (knobs or DEFAULT_KNOBS).variant("budget", budget_ms, cfg, COMPARE_SETTINGS),
                     repeat, pool=pool)
    return {"budget_ms": budget_ms, "measured_ms": chosen.gpu_ms,
            "within_budget": chosen.gpu_ms <= budget_ms * BUDGET_TOLERANCE,
            "measured_flip": metrics.flip(reference_image.image, chosen.image, ppd=ppd),
            "assignment": assignment, "config": cfg, "image": chosen.image}


def choose_under_budget(gl, scene, rig, budget_ms: float, base, reference_image,
                        ppd: float, repeat=10, progress=True, pool=None, options=None, knobs=None) -> dict:
    """Pick effects per material for `budget_ms`, render the pick and measure it.

    The per-material costs are estimates (the whole-frame passes are fixed-cost groups, but a
    traced effect's own dispatches also cost something with its first material). When the
    measured frame overshoots, or fits with more than (1 - BUDGET_SLACK) of the budget left while
    it cost less than predicted, the chosen options' costs are scaled by measured/predicted and the
    choice is solved again, at most BUDGET_ROUNDS times. From the second pick over budget on, the
    solver's budget is also lowered by the measured overshoot (scaling one material's estimate
    leaves the others' as low); a pick that then fits with slack gives the slack back. The best
    measured pick that fits is returned; if no round fits, the cheapest assignment.
    `options`: (base_ms, per-material options, fixed-cost groups) measured already, to solve
    several budgets from one measurement. `knobs`: the frame-wide knobs the pick renders with."""
    base_ms, options, fixed = options or per_material_options(gl, scene, rig, reference_image, base, ppd,
                                                              repeat=repeat, progress=progress, pool=pool, knobs=knobs)

    def attempt(opts, budget, result=None):
        result = result or solve_budget(opts, budget, base_ms=base_ms, fixed=fixed)
        return {**measure_assignment(gl, scene, rig, budget_ms, base, reference_image, ppd, result.assignment, repeat,
                                     pool, knobs),
                "predicted_ms": result.total_ms, "predicted_fixed_ms": result.fixed_ms, "feasible": result.feasible,
                "predicted_error": result.error}

    scale: dict = {}
    tried = []
    target = budget_ms  # the solver's budget: lowered by overshoots once scaling alone has not fit
    for _ in range(BUDGET_ROUNDS):
        adjusted = [MaterialOptions(
            o.name, [Option(x.effect, x.cost_ms * scale.get((o.name, x.effect), 1.0), x.error)
                     for x in o.options], importance=o.importance, coverage=o.coverage) for o in options]
        solved = solve_budget(adjusted, target, base_ms=base_ms, fixed=fixed)
        if any(p["assignment"] == solved.assignment for p in tried):
            break  # measured already: the corrections have settled
        pick = attempt(adjusted, target, solved)
        tried.append(pick)
        # the per-pixel part is what the rounds correct; the fixed groups were measured whole
        predicted_extra = pick["predicted_ms"] - base_ms - pick["predicted_fixed_ms"]
        measured_extra = pick["measured_ms"] - base_ms - pick["predicted_fixed_ms"]
        if not pick["feasible"] or predicted_extra <= 0:
            break
        factor = measured_extra / predicted_extra
        slack = budget_ms * BUDGET_SLACK - pick["measured_ms"]
        if pick["within_budget"] and (slack <= 0 or (factor >= 1.0 and target >= budget_ms)):
            break  # fits, and uses the budget (or its estimates were not high)
        if not pick["within_budget"] and len(tried) > 1:
            # scaled, and over again: the solver moves to options whose estimates are as low (a
            # path on another material); keep the measured overshoot out of its budget too
            target = max(target - (pick["measured_ms"] - budget_ms), base_ms)
        elif pick["within_budget"] and factor >= 1.0:
            target = min(target + slack, budget_ms)  # fits below a lowered budget: give the slack back
            continue
        # over: the chosen effects cost more than estimated; under: less, so the slack buys more
        for name, effect in pick["assignment"].items():
            if effect != "raster":
                scale[(name, effect)] = scale.get((name, effect), 1.0) * max(factor, MIN_COST_SCALE)
    fitting = [p for p in tried if p["within_budget"]]
    if fitting:
        best = min(fitting, key=lambda p: p["measured_flip"])
    elif tried[-1]["feasible"]:
        best = attempt(options, 0.0)  # the cheapest assignment: nothing cheaper exists
        tried.append(best)
    else:
        best = tried[-1]
    return {**best, "rounds": len(tried)}


def describe_pick(summary: dict) -> str:
    """A few lines for the terminal or the HUD."""
    state = ("within" if summary["within_budget"] else "OVER") + ("" if summary["feasible"] else " (cheapest assignment)")
    lines = [f"budget {summary['budget_ms']:.4g} ms: {state}; predicted {summary['predicted_ms']:.2f} ms, "
             f"measured {summary['measured_ms']:.2f} ms, mean FLIP {summary['measured_flip']:.4f}"]
    if summary.get("knobs") is not None:
        lines.append(f"  frame: {summary['knobs'].label}")
    for label, why in summary.get("points_refused", {}).items():
        lines.append(f"  left out {label}: {why}")
    by_effect: dict = {}
    for name, effect in summary["assignment"].items():
        by_effect.setdefault(effect, []).append(name)
    lines += [f"  {e:12s} {', '.join(sorted(n))}" for e, n in sorted(by_effect.items())]
    return "\n".join(lines)


def pick_toml(scene, summary: dict, config, size=None) -> str:
    """The pick as a config file the user can save and pass as --materials: every material's
    effect and parameters, the frame-wide knobs as its [render] table, and in its header the
    capture flags a config cannot hold (--spp, a scaled --size) and what the pick measured."""
    from ..scene.config_toml import config_toml

    names = scene.material_names()
    knobs = summary.get("knobs")
    comments = [f"rayvr budget pick for {scene.name}: {summary['budget_ms']:.4g} ms budget, "
                f"{'within' if summary['within_budget'] else 'OVER'} it: measured {summary['measured_ms']:.2f} ms, "
                f"mean FLIP {summary['measured_flip']:.4f} against the converged reference"]
    flags = knobs.capture_flags(size) if knobs is not None else ""
    if flags:
        comments.append(f"capture with: {flags}")
    return config_toml(names, config.assign(names, warn=False), render=dict(config.render), denoise=config.denoise,
                       comments=tuple(comments))
