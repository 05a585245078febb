"""Automatic per-material effects under a frame budget.

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
a multiple-choice knapsack. Costs are assumed additive (passes of different materials do not
overlap or share work), which is the approximation the measured per-material costs make.

Solver
------
Exact, on the real (not rounded) costs: dynamic programming over materials that keeps, after each
material, only the Pareto-optimal partial assignments (no other partial one is both cheaper and
lower-error) and drops those that cannot fit even with the cheapest options for the remaining
materials. The optimum is an extension of a Pareto-optimal prefix, so nothing optimal is lost.
The fronts stay small in practice (hundreds to a few thousand points for 50 materials x 7 effects),
and each step is a handful of numpy sorts.

If even the cheapest assignment exceeds the budget, the cheapest one (ties broken by error) is
returned with ``feasible=False`` instead of raising.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Slack for floating-point sums when comparing against the budget (1 ns in ms units).
COST_EPS_MS = 1e-6


@dataclass(frozen=True)
class Option:
    """One effect a material can use, with its measured cost (ms) and error."""

    effect: str
    cost_ms: float
    error: float


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


def solve_budget(materials, budget_ms: float, base_ms: float = 0.0) -> BudgetResult:
    """Choose one option per material minimising weighted error with total ms <= budget_ms.

    See the module docstring for the model. Exact; ``feasible=False`` (with the cheapest
    assignment) when even that exceeds the budget.
    """
    mats = as_materials(materials)
    budget_ms = _finite(budget_ms, "budget_ms", nonneg=False)
    base_ms = _finite(base_ms, "base_ms")

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
