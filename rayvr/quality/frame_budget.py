"""The budget over the whole frame: per-material effects and the frame-wide knobs together
(`--budget-ms` / `--budget-hz` with `--frame-knobs`, `rayvr bench budget`).

Model
-----
For every point F of the knob grid (quality/frame_knobs.py) the per-material table is measured
with F (budget.per_material_options: one render per rung of the ladder, all with F), so F's
interaction with every effect is measured, not assumed: `reuse` changes what each traced effect
costs, the denoiser's cost follows the effects it filters, a lower scale raises every error.
F's whole-frame passes (the denoiser, the quadtree) are its fixed-cost groups, paid once when any
material takes an effect that runs them (budget.fixed_costs, from the renders' pass timers).
F's best assignment is budget.solve_budget on F's table; the frame's pick is the F whose best
has the least error. That is exact for the model: every F is solved exactly and compared.

The pick is then rendered and measured (budget.choose_under_budget, which corrects its cost
estimates a few rounds); when its F does not fit on the measured frame, the next-best F is
tried. A pick that fits no budget is reported `within_budget: False`, never silently.

`grid_best` is the exhaustive search of the measured grid itself: every F with every material on
one rung, the renders the tables came from; the pick's measured FLIP against the best of those
that fit is the solver's optimality gap as `rayvr bench budget` reports it. Those renders are
measured frames, so one that beats every solved pick is the answer (`from_grid`); the solved
pick's own FLIP stays in `solver_flip`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from . import metrics
from .budget import BUDGET_TOLERANCE, BudgetResult, FixedCost, MaterialOptions, choose_under_budget, \
    measure_assignment, measure_rungs, options_from_rungs, solve_budget
from .measure import (BENCH_QUALITY, QUICK_REFERENCE_SPP, RendererPool, measure_reference, reference_per_frame,
                      reference_variant)
from .reference_images import reference_config
from .frame_knobs import FrameKnobs

# --budget-ms in capture and preview: the user waits for the reference, so it has fewer samples than
# the bench's (REFERENCE_SPP); a noisier reference raises every candidate's FLIP (docs/budget.md).
AUTO_REFERENCE_SPP = 256

FRAME_TRIES = 3  # points of the grid rendered, best predicted first, before a pick is reported over budget


@dataclass
class FrameCandidate:
    """One point of the knob grid with what was measured under it."""

    knobs: FrameKnobs
    base_ms: float  # the all-raster frame with these knobs
    materials: list[MaterialOptions]
    rungs: dict  # {effect: (GPU ms, mean FLIP)} of the whole scene on that rung, with these knobs
    fixed: list[FixedCost] = field(default_factory=list)  # its whole-frame passes (budget.fixed_costs)


@dataclass
class FramePick:
    knobs: FrameKnobs
    result: BudgetResult

    @property
    def feasible(self) -> bool:
        return self.result.feasible


def solve_frame_budget(candidates: list[FrameCandidate], budget_ms: float) -> FramePick:
    """The knobs and per-material effects of least predicted error within `budget_ms`; when no
    point fits, the cheapest frame of any point, infeasible."""
    return ranked_picks(candidates, budget_ms)[0]


def ranked_picks(candidates: list[FrameCandidate], budget_ms: float) -> list[FramePick]:
    """Every point's exact best for `budget_ms`, the feasible ones first by predicted error
    (then cost), then the infeasible ones cheapest first."""
    if not candidates:
        raise ValueError("the frame budget needs at least one point of the knob grid")
    picks = [FramePick(c.knobs, solve_budget(c.materials, budget_ms, base_ms=c.base_ms, fixed=c.fixed))
             for c in candidates]
    return sorted(picks, key=lambda p: (not p.feasible, p.result.error if p.feasible else 0.0, p.result.total_ms))


def measure_candidates(gl, scene, rig, reference_image, base, ppd: float, grid: list[FrameKnobs], repeat=10,
                       progress=True, pool=None, measure_all=None, rungs=None) -> tuple[list[FrameCandidate], dict]:
    """The per-material tables of every point of `grid` over `rungs` (keys, quality/rungs.py;
    default the ladder's effects), and {point's label: why} for the points the renderer refuses
    (e.g. `reuse` with MSAA): left out. ValueError when it refuses them all."""
    out, refused = [], {}
    for knobs in grid:
        try:
            measured = measure_rungs(gl, scene, rig, reference_image, base, ppd, effects=rungs, repeat=repeat,
                                     progress=progress, pool=pool, measure_all=measure_all, knobs=knobs)
        except ValueError as exc:  # a combination the frame plan refuses, before any work
            refused[knobs.label] = str(exc)
            continue
        base_ms, materials, fixed = options_from_rungs(scene, reference_image, base, measured)
        out.append(FrameCandidate(knobs, base_ms, materials,
                                  {e: (r[0], float(r[1].mean())) for e, r in measured.items()}, fixed))
    if not out:
        label, why = next(iter(refused.items()))
        raise ValueError(f"no point of the frame-knob grid renders here: {label}: {why}")
    return out, refused


def grid_best(candidates: list[FrameCandidate], budget_ms: float) -> dict | None:
    """The best measured render of the grid (a point, every material on one rung) within
    `budget_ms` (timer tolerance as the pick's), or None when none fits."""
    fitting = [(flip, ms, c.knobs, e) for c in candidates for e, (ms, flip) in c.rungs.items()
               if ms <= budget_ms * BUDGET_TOLERANCE]
    if not fitting:
        return None
    flip, ms, knobs, effect = min(fitting, key=lambda t: (t[0], t[1]))
    return {"flip": flip, "gpu_ms": ms, "knobs": knobs.label, "effect": effect}


def choose_frame_under_budget(gl, scene, rig, budget_ms: float, base, reference_image, ppd: float,
                              candidates: list[FrameCandidate], repeat=10, progress=True, pool=None) -> dict:
    """Render the best points' picks (at most FRAME_TRIES) until one fits `budget_ms` on the
    measured frame; the pick with its knobs (its config's [render] table holds them too), or the
    best tried, `within_budget` False."""
    tried = []
    for pick in ranked_picks(candidates, budget_ms)[:FRAME_TRIES]:
        c = next(c for c in candidates if c.knobs == pick.knobs)
        got = choose_under_budget(gl, scene, rig, budget_ms, base, reference_image, ppd, repeat, progress, pool,
                                  options=(c.base_ms, c.materials, c.fixed), knobs=c.knobs)
        got = {**got, "knobs": c.knobs, "config": replace(got["config"], render=c.knobs.render_table())}
        tried.append(got)
        if got["within_budget"]:
            break
    fitting = [t for t in tried if t["within_budget"]]
    best = min(fitting, key=lambda t: t["measured_flip"]) if fitting else min(tried, key=lambda t: t["measured_ms"])
    solved = {"solver_flip": best["measured_flip"] if fitting else None, "points_tried": len(tried),
              # the solved pick as measured, kept when a grid render replaces it: what the model got wrong
              "solver_pick": {k: best.get(k) for k in ("predicted_ms", "predicted_fixed_ms", "predicted_error",
                                                      "measured_ms", "measured_flip", "within_budget", "rounds")}}
    # The grid's own renders (a point, the whole scene on one rung) are measured already: one that
    # fits with less error than every solved pick is the better answer (the model's per-material
    # split of costs and errors is an estimate). Rendered again for its image and a fresh time.
    whole = grid_best(candidates, budget_ms)
    if whole is not None and (not fitting or whole["flip"] < best["measured_flip"]):
        c = next(c for c in candidates if c.knobs.label == whole["knobs"])
        got = measure_assignment(gl, scene, rig, budget_ms, base, reference_image, ppd,
                                 {n: whole["effect"] for n in scene.material_names()}, repeat, pool, c.knobs)
        if got["within_budget"] and (not fitting or got["measured_flip"] < best["measured_flip"]):
            best = {**got, "predicted_ms": whole["gpu_ms"], "feasible": True, "predicted_error": whole["flip"],
                    "rounds": 1, "knobs": c.knobs, "config": replace(got["config"], render=c.knobs.render_table()),
                    "from_grid": True}
    return {"from_grid": False, **best, **solved}


def auto_config(renderer, rig, budget_ms: float, ppd: float | None = None, repeat: int = 5,
                progress: bool = True, grid=None):
    """`--budget-ms` for capture and preview: effects per material of `renderer.scene` that keep the
    frame within `budget_ms` on this device with the least error, starting from the renderer's
    current config. With `grid` (a list of quality/frame_knobs.FrameKnobs) the frame-wide knobs
    are chosen too: the summary's "knobs" and the config's [render] table hold them. Returns the config and the summary (predicted and measured ms and FLIP)."""
    ppd = metrics.DEFAULT_PPD if ppd is None else ppd

    gl, scene = renderer.gl, renderer.scene
    quick = gl.is_software
    reference = reference_variant(reference_config(scene, quick=quick, quality=None if quick else BENCH_QUALITY))
    with RendererPool(gl) as pool:
        ref = measure_reference(gl, scene, rig, reference, QUICK_REFERENCE_SPP if quick else AUTO_REFERENCE_SPP,
                                reference_per_frame(quick), pool).measured
        if grid:
            candidates, refused = measure_candidates(gl, scene, rig, ref, renderer.config, ppd, grid, repeat,
                                                     progress, pool)
            pick = choose_frame_under_budget(gl, scene, rig, budget_ms, renderer.config, ref, ppd, candidates, repeat,
                                             progress, pool)
            pick["points_refused"] = refused
        else:
            pick = choose_under_budget(gl, scene, rig, budget_ms, renderer.config, ref, ppd, repeat, progress, pool)
    summary = {k: v for k, v in pick.items() if k not in ("config", "image")}
    return pick["config"], summary
