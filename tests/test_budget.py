import itertools
import time

import numpy as np
import pytest

from rayvr.quality.budget import COST_EPS_MS, MaterialOptions, Option, solve_budget

# A ladder like rayvr's: each step up costs more and errs less.
LADDER = ["raster", "ssr", "ssrt", "rt1", "rt2", "rt4", "path"]


def _random_materials(rng, n, k, ladder=True, cheap_first=False):
    mats = []
    for i in range(n):
        cost = np.sort(rng.uniform(0.0, 1.0, k))
        if cheap_first:  # the raster rung costs next to nothing, as in a real ladder
            cost[0] = rng.uniform(0.0, 0.02)
        err = np.sort(rng.uniform(0.0, 1.0, k))[::-1] if ladder else rng.uniform(0.0, 1.0, k)
        mats.append({
            "name": f"m{i}",
            "options": [(LADDER[j % len(LADDER)] + str(j), cost[j], err[j]) for j in range(k)],
            "importance": rng.uniform(0.5, 2.0),
            "coverage": rng.uniform(0.0, 0.3),
        })
    return mats


def _brute_force(mats, budget, base, groups=()):
    """Every assignment; each fixed-cost group charged once where any material takes one of its effects."""
    best = None
    for choice in itertools.product(*(range(len(m["options"])) for m in mats)):
        used = {m["options"][i][0] for m, i in zip(mats, choice)}
        cost = base + sum(m["options"][i][1] for m, i in zip(mats, choice)) + sum(
            g.cost_ms for g in groups if g.effects & used)
        if cost > budget + COST_EPS_MS:
            continue
        err = sum(m["importance"] * m["coverage"] * m["options"][i][2] for m, i in zip(mats, choice))
        if best is None or err < best[0]:
            best = (err, cost, choice)
    return best


def test_known_optimum():
    # Greedy by error-per-ms would upgrade "a" (best ratio) first and then have no room for "b".
    mats = [
        MaterialOptions("a", [Option("raster", 0.0, 1.0), Option("rt1", 1.0, 0.5)]),
        MaterialOptions("b", [Option("raster", 0.0, 2.0), Option("rt1", 2.0, 0.9)]),
        MaterialOptions("c", [Option("raster", 0.0, 0.2), Option("rt1", 1.5, 0.0)]),
    ]
    r = solve_budget(mats, budget_ms=3.0, base_ms=0.5)
    assert r.feasible
    assert r.assignment == {"a": "raster", "b": "rt1", "c": "raster"}
    assert r.total_ms == pytest.approx(2.5)
    assert r.error == pytest.approx(1.0 + 0.9 + 0.2)
    # Importance steers the choice: make "c" matter a lot and it gets the upgrade instead.
    mats[2].importance = 20.0
    r = solve_budget(mats, budget_ms=3.0, base_ms=0.5)
    assert r.assignment == {"a": "rt1", "b": "raster", "c": "rt1"}
    assert r.error == pytest.approx(0.5 + 2.0 + 0.0)


def test_generous_and_zero_budget():
    mats = [MaterialOptions("m", [Option("raster", 0.1, 1.0), Option("ssr", 0.4, 0.3),
                                   Option("path", 3.0, 0.0)])]
    assert solve_budget(mats, 100.0).assignment == {"m": "path"}
    assert solve_budget(mats, 0.1).assignment == {"m": "raster"}
    r = solve_budget([], 1.0, base_ms=0.5)
    assert r.feasible and r.total_ms == 0.5 and r.assignment == {}


def test_over_budget_returns_cheapest_with_flag():
    mats = [
        {"name": "a", "options": [("raster", 1.0, 0.5), ("cheap", 1.0, 0.4), ("rt", 2.0, 0.1)]},
        {"name": "b", "options": [("ssr", 0.5, 0.3), ("rt", 3.0, 0.0)]},
    ]
    r = solve_budget(mats, budget_ms=2.0, base_ms=1.0)
    assert not r.feasible
    # Cheapest per material, ties broken by lower error.
    assert r.assignment == {"a": "cheap", "b": "ssr"}
    assert r.total_ms == pytest.approx(2.5)
    assert r.summary()["feasible"] is False


@pytest.mark.parametrize("seed", range(40))
def test_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, k = rng.integers(1, 6), rng.integers(1, 5)
    mats = _random_materials(rng, n, k, ladder=bool(seed % 2))
    base = rng.uniform(0, 0.5)
    budget = base + rng.uniform(0, 0.6 * n)
    r = solve_budget(mats, budget, base)
    bf = _brute_force(mats, budget, base)
    if bf is None:
        assert not r.feasible
        return
    assert r.feasible
    assert r.total_ms <= budget + COST_EPS_MS
    assert r.error == pytest.approx(bf[0], abs=1e-12)


def test_respects_budget_at_scale():
    rng = np.random.default_rng(123)
    mats = _random_materials(rng, 50, 7, cheap_first=True)
    base = 1.5
    errors = []
    for budget in (2.0, 4.0, 8.0, 16.0):
        t0 = time.perf_counter()
        r = solve_budget(mats, budget, base)
        assert time.perf_counter() - t0 < 2.0
        assert r.feasible and r.total_ms <= budget + COST_EPS_MS
        # total_ms and error match the reported rows
        rows = r.rows()
        assert r.total_ms == pytest.approx(base + sum(x["cost_ms"] for x in rows))
        assert r.error == pytest.approx(sum(x["weighted_error"] for x in rows))
        errors.append(r.error)
    # More budget never makes the optimum worse.
    assert errors == sorted(errors, reverse=True)


def test_validation():
    with pytest.raises(ValueError, match="twice"):
        solve_budget([{"name": "a", "options": [("x", 1, 1)]}] * 2, 5)
    with pytest.raises(ValueError, match="no options"):
        solve_budget([{"name": "a", "options": []}], 5)
    with pytest.raises(ValueError, match="cost_ms"):
        solve_budget([{"name": "a", "options": [("x", -1, 1)]}], 5)
    with pytest.raises(ValueError, match="error"):
        solve_budget([{"name": "a", "options": [("x", 1, float("nan"))]}], 5)
    with pytest.raises(ValueError, match="coverage"):
        solve_budget([{"name": "a", "options": [("x", 1, 1)], "coverage": -0.1}], 5)
    with pytest.raises(TypeError, match="option"):
        solve_budget([{"name": "a", "options": ["x"]}], 5)


# ------------------------------------------------------------ fixed-cost groups (whole-frame passes)

@pytest.mark.parametrize("seed", range(40))
def test_fixed_cost_groups_match_brute_force(seed):
    from rayvr.quality.budget import FixedCost

    rng = np.random.default_rng(1000 + seed)
    n, k = rng.integers(1, 5), rng.integers(2, 5)
    effects = [f"e{j}" for j in range(k)]
    mats = [{"name": f"m{i}", "importance": 1.0, "coverage": rng.uniform(0.05, 0.4),
             "options": [(e, rng.uniform(0, 0.5) * (j > 0), rng.uniform(0, 1) / (1 + j)) for j, e in enumerate(effects)]}
            for i in range(n)]
    # e0 stays free of groups (it is `raster`); the others share 1-6 groups (nested, as layers, or not)
    groups = [FixedCost(f"g{g}", float(rng.uniform(0.1, 1.5)),
                        frozenset(rng.choice(effects[1:], size=rng.integers(1, k), replace=False)))
              for g in range(rng.integers(1, 7))]
    base = rng.uniform(0, 0.5)
    budget = base + rng.uniform(0, 0.5 * n + 1.5)
    r = solve_budget(mats, budget, base, fixed=groups)
    bf = _brute_force(mats, budget, base, groups)
    if bf is None:
        assert not r.feasible
        return
    assert r.feasible and r.total_ms <= budget + COST_EPS_MS
    assert r.error == pytest.approx(bf[0], abs=1e-12)
    used = set(r.assignment.values())
    charged = [g for g in groups if g.effects & used]
    assert sorted(r.fixed) == sorted(g.name for g in charged)
    assert r.total_ms == pytest.approx(base + sum(x["cost_ms"] for x in r.rows()) + sum(g.cost_ms for g in charged))


def test_a_denoised_sliver_pays_the_whole_denoiser():
    """Path on a 10 % material costs 0.4 ms of its pixels but the denoiser's 3.5 ms as well: with
    3.55 ms over the base no denoised effect fits (without the group the solver would predict
    path and shadows at 0.6 ms); with 4.2 ms path and shadows share the one denoiser."""
    from rayvr.quality.budget import FixedCost

    mats = [MaterialOptions("small", [Option("raster", 0.0, 0.6), Option("shadows", 0.1, 0.55), Option("path", 0.4, 0.1)],
                            coverage=0.1),
            MaterialOptions("big", [Option("raster", 0.0, 0.6), Option("shadows", 0.2, 0.5), Option("path", 20.0, 0.1)],
                            coverage=0.9)]
    denoiser = FixedCost("denoise", 3.5, frozenset({"shadows", "path"}))
    plain = solve_budget(mats, 2.0 + 3.55, base_ms=2.0)
    assert plain.assignment == {"small": "path", "big": "shadows"} and plain.total_ms == pytest.approx(2.6)
    r = solve_budget(mats, 2.0 + 3.55, base_ms=2.0, fixed=[denoiser])
    assert r.assignment == {"small": "raster", "big": "raster"} and r.fixed_ms == 0.0
    r = solve_budget(mats, 2.0 + 4.2, base_ms=2.0, fixed=[denoiser])
    assert r.assignment == {"small": "path", "big": "shadows"} and r.fixed == ("denoise",)
    assert r.total_ms == pytest.approx(2.0 + 0.4 + 0.2 + 3.5)


def test_fixed_costs_come_from_the_passes_a_rung_adds_over_raster():
    """Made-up pass timers: `denoise` (shadows and photon 3.5 ms, path 3.4 ms), `quadtree` (ssr) and
    the photon map's passes are groups;
    rt_* passes and the shrinking `shade` stay per pixel; each whole-scene render is predicted
    exactly from the base, its groups and its per-pixel part."""
    from rayvr.quality.budget import fixed_costs

    flip = np.zeros(4)
    rungs = {"raster": (3.0, flip, {"gbuffer": 1.0, "shade": 2.0}),
             "shadows": (7.0, flip, {"gbuffer": 1.0, "shade": 1.5, "classify": 0.02, "rt_shadows": 1.0, "denoise": 3.5}),
             "path": (14.4, flip, {"gbuffer": 1.0, "shade": 1.0, "rt_path": 9.0, "denoise": 3.4}),
             "ssr": (5.0, flip, {"gbuffer": 1.08, "shade": 1.5, "quadtree": 0.8, "rt_ssr": 1.62}),
             "photon": (7.4, flip, {"gbuffer": 1.0, "shade": 1.9, "photon_trace": 0.5, "photon_sort": 0.3,
                                    "rt_photon": 0.2, "denoise": 3.5})}
    groups, per_pixel = fixed_costs(rungs)
    by_name = {g.name: g for g in groups}
    # classify's 0.02 ms is under FIXED_COST_MIN_MS, the gbuffer's 8 % growth under FIXED_COST_NOISE
    assert set(by_name) == {"denoise", "quadtree", "photon_sort+photon_trace"}  # one group: the same rungs run them
    assert by_name["denoise"].effects == {"shadows", "path", "photon"} and by_name["denoise"].cost_ms == pytest.approx(3.5)
    assert by_name["photon_sort+photon_trace"].cost_ms == pytest.approx(0.8)
    assert by_name["quadtree"].effects == {"ssr"} and by_name["quadtree"].cost_ms == pytest.approx(0.8)
    assert per_pixel["raster"] == 0.0
    for e, (ms, _, _) in rungs.items():
        charged = sum(g.cost_ms for g in groups if e in g.effects)
        assert rungs["raster"][0] + charged + per_pixel[e] == pytest.approx(ms), e
    # without pass timers (a measurer that has none) everything is per pixel, as before
    groups, per_pixel = fixed_costs({e: r[:2] for e, r in rungs.items()})
    assert groups == [] and per_pixel["path"] == pytest.approx(11.4)


def test_a_pass_some_rungs_grow_far_more_is_charged_at_the_costliest_rung_a_frame_takes():
    """The denoiser grows by 0.5 ms for `shadows`, 1.5 for `glossy` and 3.0 for `path`. Charging
    every frame that denoises the most (3.0 ms) predicted the whole-scene `shadows` render at 5 ms
    (its 0.5 ms per-pixel share could not pay the 2.5 ms difference) where it measured 3. As layers
    (0.5 with all three, 1.0 more with glossy and path, 1.5 more with path) a frame pays what its
    costliest rung grows the pass by, and every whole-scene render is predicted exactly."""
    import itertools

    from rayvr.quality.budget import fixed_costs

    flip = np.zeros(4)
    rungs = {"raster": (2.0, flip, {"gbuffer": 1.0, "shade": 1.0}),
             "shadows": (3.0, flip, {"gbuffer": 1.0, "shade": 0.9, "rt_shadows": 0.6, "denoise": 0.5}),
             "glossy": (4.0, flip, {"gbuffer": 1.0, "shade": 0.8, "rt_glossy": 1.0, "denoise": 1.5}),
             "path": (9.0, flip, {"gbuffer": 1.0, "shade": 0.5, "rt_path": 4.0, "denoise": 3.0})}
    groups, per_pixel = fixed_costs(rungs)
    assert {g.name: (g.cost_ms, set(g.effects)) for g in groups} == {
        "denoise": (pytest.approx(0.5), {"shadows", "glossy", "path"}),
        "denoise+1": (pytest.approx(1.0), {"glossy", "path"}), "denoise+2": (pytest.approx(1.5), {"path"})}
    for e, (ms, _, _) in rungs.items():
        assert rungs["raster"][0] + per_pixel[e] + sum(g.cost_ms for g in groups if e in g.effects) == \
            pytest.approx(ms), e
    growth = {"raster": 0.0, "shadows": 0.5, "glossy": 1.5, "path": 3.0}
    for k in range(1, 4):
        for taken in itertools.combinations(growth, k):  # a frame with these rungs pays the most they grow it
            charged = sum(g.cost_ms for g in groups if g.effects & set(taken))
            assert charged == pytest.approx(max(growth[e] for e in taken)), taken


def test_a_pick_whose_every_estimate_is_low_ends_within_budget_not_on_the_cheapest(monkeypatch):
    """Every material's `path` truly costs twice its estimate. Scaling the chosen materials'
    estimates moves the pick onto others as underestimated; lowering the solver's budget by the
    overshoot ends on a measured pick within budget that still traces, not on the all-raster frame."""
    from rayvr.quality import budget

    true_ms = {f"m{i}": 2.0 for i in range(8)}
    options = [MaterialOptions(m, [Option("raster", 0.0, 0.5), Option("path", 1.0, 0.1)], coverage=0.125)
               for m in true_ms]
    renders = []

    def render(gl, scene, rig, budget_ms, base, ref, ppd, assignment, repeat, pool, knobs):
        ms = 1.0 + sum(true_ms[m] for m, e in assignment.items() if e == "path")
        renders.append(ms)
        flip = sum(0.125 * (0.1 if e == "path" else 0.5) for e in assignment.values())
        return {"budget_ms": budget_ms, "measured_ms": ms, "within_budget": ms <= budget_ms * budget.BUDGET_TOLERANCE,
                "measured_flip": flip, "assignment": assignment, "config": None, "image": None}

    monkeypatch.setattr(budget, "measure_assignment", render)
    got = budget.choose_under_budget(None, None, None, 6.0, None, None, 60.0, options=(1.0, options, []))
    assert got["within_budget"] and got["measured_ms"] <= 6.0
    assert list(got["assignment"].values()).count("path") == 2  # the most that truly fits 5 ms
    assert got["rounds"] <= budget.BUDGET_ROUNDS and len(renders) == got["rounds"]
