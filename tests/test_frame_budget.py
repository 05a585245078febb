"""The budget over the whole frame (quality/frame_budget.py, frame_knobs.py): the solver against a
brute force over knobs x assignments, infeasible and over-budget picks reported, the grid's
parsing, the saved pick reloading as itself, and the reference never sharing a variant's seed."""
import itertools

import numpy as np
import pytest

from conftest import needs_flip, run_rayvr
from rayvr.quality import frame_budget as fb
from rayvr.quality.budget import COST_EPS_MS, MaterialOptions, Option
from rayvr.quality.frame_knobs import DEFAULT_KNOBS, FrameKnobs, budget_ms_of, parse_grid

DUAL, REUSE = FrameKnobs(stereo="dual"), FrameKnobs(stereo="reuse")


def candidate(knobs, base_ms, table):
    """table: {material: [(effect, extra ms, error), ...]}"""
    mats = [MaterialOptions(m, [Option(*o) for o in opts]) for m, opts in table.items()]
    return fb.FrameCandidate(knobs, base_ms, mats, {})


def brute_force(candidates, budget):
    best = None
    for c in candidates:
        for choice in itertools.product(*(range(len(m.options)) for m in c.materials)):
            cost = c.base_ms + sum(m.options[i].cost_ms for m, i in zip(c.materials, choice))
            if cost > budget + COST_EPS_MS:
                continue
            err = sum(m.weight * m.options[i].error for m, i in zip(c.materials, choice))
            if best is None or err < best[0] - 1e-12:
                best = (err, c.knobs)
    return best


def test_a_knob_that_makes_traced_effects_cheaper_wins_the_budget():
    # dual: the glossy floor does not fit 6 ms; reuse halves its cost and costs a little error
    # of its own everywhere: at 6 ms reuse + glossy beats dual + raster, at 20 ms dual + glossy wins.
    dual = candidate(DUAL, 2.0, {"floor": [("raster", 0.0, 0.30), ("glossy", 8.0, 0.05)],
                                 "wall": [("raster", 0.0, 0.10), ("shadows", 1.0, 0.04)]})
    reuse = candidate(REUSE, 1.5, {"floor": [("raster", 0.0, 0.31), ("glossy", 4.0, 0.07)],
                                   "wall": [("raster", 0.0, 0.11), ("shadows", 0.5, 0.05)]})
    tight = fb.solve_frame_budget([dual, reuse], 6.0)
    assert tight.feasible and tight.knobs == REUSE
    assert tight.result.assignment == {"floor": "glossy", "wall": "shadows"}
    assert tight.result.error == pytest.approx(0.07 + 0.05)
    wide = fb.solve_frame_budget([dual, reuse], 20.0)
    assert wide.knobs == DUAL and wide.result.error == pytest.approx(0.05 + 0.04)
    # with 3 ms only raster fits either way; reuse's raster frame is the only one with shadows room
    low = fb.solve_frame_budget([dual, reuse], 2.5)
    assert low.knobs == REUSE and low.result.assignment == {"floor": "raster", "wall": "shadows"}


@pytest.mark.parametrize("seed", range(6))
def test_solver_matches_brute_force_over_knobs_and_assignments(seed):
    rng = np.random.default_rng(seed)
    grid = parse_grid("stereo=dual,warp,reuse;denoise=off,on")
    candidates = []
    for knobs in grid:
        table = {f"m{i}": [(f"e{j}", float(c), float(e)) for j, (c, e) in
                           enumerate(zip(np.sort(rng.uniform(0, 3, 4)), np.sort(rng.uniform(0, 1, 4))[::-1]))]
                 for i in range(4)}
        candidates.append(candidate(knobs, float(rng.uniform(0.5, 2.0)), table))
    for budget in (1.0, 3.0, 6.0, 12.0):
        want = brute_force(candidates, budget)
        got = fb.solve_frame_budget(candidates, budget)
        if want is None:
            assert not got.feasible
            continue
        assert got.feasible and got.result.total_ms <= budget + COST_EPS_MS
        assert got.result.error == pytest.approx(want[0], abs=1e-12)


def test_nothing_fits_gives_the_cheapest_frame_marked_infeasible():
    a = candidate(DUAL, 5.0, {"m": [("raster", 0.5, 1.0), ("path", 9.0, 0.0)]})
    b = candidate(REUSE, 4.0, {"m": [("raster", 0.2, 1.1), ("path", 5.0, 0.1)]})
    pick = fb.solve_frame_budget([a, b], 3.0)
    assert not pick.feasible and pick.knobs == REUSE
    assert pick.result.total_ms == pytest.approx(4.2)
    with pytest.raises(ValueError, match="at least one point"):
        fb.solve_frame_budget([], 3.0)


def test_a_pick_over_its_budget_on_the_measured_frame_is_reported_not_hidden(monkeypatch):
    """Every point tried measures over the budget: the result says so, after FRAME_TRIES points."""
    from rayvr.scene.materials import MaterialConfig

    calls = []

    def over(gl, scene, rig, budget_ms, base, ref, ppd, repeat, progress, pool, options, knobs):
        calls.append(knobs)
        return {"budget_ms": budget_ms, "measured_ms": budget_ms * 1.5 + len(calls), "within_budget": False,
                "feasible": True, "measured_flip": 0.1, "assignment": {}, "config": MaterialConfig()}

    monkeypatch.setattr(fb, "choose_under_budget", over)
    grid = parse_grid("stereo=dual,warp,reuse;denoise=off,on")
    candidates = [candidate(k, 1.0 + i, {"m": [("raster", 0.0, 0.5)]}) for i, k in enumerate(grid)]
    got = fb.choose_frame_under_budget(None, None, None, 4.0, None, None, 60.0, candidates)
    assert got["within_budget"] is False and got["points_tried"] == fb.FRAME_TRIES == len(calls)
    assert calls[0] == grid[0]  # the cheapest (all raster ties on error): the best predicted first
    assert got["measured_ms"] == min(4.0 * 1.5 + n for n in range(1, fb.FRAME_TRIES + 1))
    assert got["config"].render == got["knobs"].render_table()  # the config to save carries the knobs


def test_a_grid_render_that_measured_better_than_the_solved_pick_is_the_answer(monkeypatch):
    """The solver's per-material pick measures FLIP 0.3; the grid's render with every material on
    `glossy` under REUSE fits at 0.15: the answer is that render, measured again, and the solver's
    own figure is kept beside it. Where the grid's best is worse, the solver's pick stays."""
    from rayvr.scene.materials import MaterialConfig

    class Scene:
        def material_names(self):
            return ["a", "b"]

    def solved(gl, scene, rig, budget_ms, base, ref, ppd, repeat, progress, pool, options, knobs):
        return {"budget_ms": budget_ms, "measured_ms": 5.0, "within_budget": True, "feasible": True,
                "measured_flip": 0.3, "predicted_ms": 5.0, "assignment": {"a": "shadows"}, "config": MaterialConfig()}

    rendered = []

    def render(gl, scene, rig, budget_ms, base, ref, ppd, assignment, repeat, pool, knobs):
        rendered.append((assignment, knobs))
        return {"budget_ms": budget_ms, "measured_ms": 5.1, "within_budget": True, "measured_flip": 0.15,
                "assignment": assignment, "config": MaterialConfig(), "image": None}

    monkeypatch.setattr(fb, "choose_under_budget", solved)
    monkeypatch.setattr(fb, "measure_assignment", render)

    def points(reuse_glossy_flip):
        opts = [MaterialOptions("a", [Option("raster", 0.0, 0.5), Option("shadows", 3.0, 0.3)])]
        return [fb.FrameCandidate(DUAL, 1.0, opts, {"raster": (1.0, 0.5), "glossy": (9.0, 0.1)}),
                fb.FrameCandidate(REUSE, 1.0, opts, {"raster": (0.8, 0.52), "glossy": (5.0, reuse_glossy_flip)})]

    got = fb.choose_frame_under_budget(None, Scene(), None, 6.0, None, None, 60.0, points(0.15))
    assert rendered == [({"a": "glossy", "b": "glossy"}, REUSE)]  # DUAL's better glossy does not fit 6 ms
    assert got["from_grid"] and got["knobs"] == REUSE and got["assignment"] == {"a": "glossy", "b": "glossy"}
    assert got["measured_flip"] == 0.15 and got["solver_flip"] == 0.3
    assert got["config"].render == REUSE.render_table()
    rendered.clear()
    got = fb.choose_frame_under_budget(None, Scene(), None, 6.0, None, None, 60.0, points(0.35))
    assert not rendered and not got["from_grid"] and got["measured_flip"] == got["solver_flip"] == 0.3


def test_grid_best_is_the_least_error_render_that_fits():
    a = fb.FrameCandidate(DUAL, 1.0, [], {"raster": (1.0, 0.5), "glossy": (9.0, 0.1)})
    b = fb.FrameCandidate(REUSE, 1.0, [], {"raster": (0.8, 0.52), "glossy": (5.0, 0.15)})
    assert fb.grid_best([a, b], 6.0) == {"flip": 0.15, "gpu_ms": 5.0, "knobs": REUSE.label, "effect": "glossy"}
    assert fb.grid_best([a, b], 0.5) is None


def test_grid_parsing():
    grid = parse_grid("stereo=dual,reuse; spp=1,4 ;denoise=off,on;msaa=1;scale=0.75,1")
    assert len(grid) == 2 * 2 * 2 * 1 * 2
    assert FrameKnobs("reuse", 4, True, 1, 0.75) in grid
    assert parse_grid(None) == parse_grid("") == [DEFAULT_KNOBS]
    assert parse_grid("stereo=dual,dual") == [DEFAULT_KNOBS]
    # knobs the grid leaves out keep the command's own values
    assert parse_grid("stereo=dual,reuse", FrameKnobs(msaa=4, denoise=True)) == [
        FrameKnobs("dual", 1, True, 4, 1.0), FrameKnobs("reuse", 1, True, 4, 1.0)]
    for bad, says in [("stereo=mono", "stereo"), ("fps=90", "KNOB=VALUE"), ("spp=0", "spp"), ("msaa=3", "msaa"),
                      ("scale=0.1", "scale"), ("denoise=yes please", "denoise"), ("spp=1;spp=2", "twice"),
                      ("scale=", "no values"), ("stereo", "KNOB=VALUE"), ("temporal=sometimes", "temporal"),
                      ("camera=distorted", "the pinhole reference can judge")]:
        with pytest.raises(ValueError, match=says):
            parse_grid(bad)
    assert budget_ms_of(90) == pytest.approx(11.111, abs=1e-3) and budget_ms_of(120) == pytest.approx(8.333, abs=1e-3)
    # the denoiser's iterations: a point each where it is on, one point where it is off
    assert parse_grid("denoise=off,on;iterations=2,4") == [FrameKnobs(), FrameKnobs(denoise=True, iterations=2),
                                                           FrameKnobs(denoise=True, iterations=4)]
    with pytest.raises(ValueError, match="iterations: '9' is not a whole number from 1 to 6"):
        parse_grid("iterations=9")
    assert parse_grid("temporal=off,on;camera=pinhole,foveated") == [
        FrameKnobs(temporal=t, camera=c) for t in (False, True) for c in ("pinhole", "foveated")]


def test_knobs_become_render_options_and_capture_flags():
    from rayvr.quality.measure import COMPARE_SETTINGS

    k = FrameKnobs("reuse", 4, True, 4, 0.75)
    s = k.settings(COMPARE_SETTINGS)
    assert (s.stereo, s.denoise, s.msaa) == ("reuse", True, 4)
    assert s.tonemapper == COMPARE_SETTINGS.tonemapper  # the rest stays the comparison's
    assert k.capture_flags((1440, 1600)) == "--spp 4 --size 1080x1200"
    assert DEFAULT_KNOBS.capture_flags((1440, 1600)) == ""
    v = k.variant("budget", "glossy", None, COMPARE_SETTINGS)
    assert (v.spp, v.scale, v.settings.stereo, v.camera) == (4, 0.75, "reuse", None)  # None: the rig's camera
    s2 = FrameKnobs(denoise=True, iterations=2).settings(COMPARE_SETTINGS)
    assert s2.denoise and s2.denoise_iterations == 2
    assert "denoise_iterations" not in FrameKnobs(denoise=True).render_table()  # the default stays implicit
    f = FrameKnobs(temporal=True, camera="foveated")
    v = f.variant("budget", "glossy", None, COMPARE_SETTINGS)
    assert v.settings.temporal and v.camera == "foveated" and f.render_table()["temporal"] is True
    assert v.settings.accumulate  # what --temporal implies: without it a still view's image is one frame's
    assert not DEFAULT_KNOBS.settings(COMPARE_SETTINGS).accumulate
    assert f.capture_flags((1440, 1600)) == "--camera-model foveated"


def test_saved_pick_loads_back_as_the_same_config(tmp_path):
    from rayvr.quality.budget import pick_toml
    from rayvr.scene.materials import MaterialConfig, load_config

    class Scene:
        name = "test"

        def material_names(self):
            return ["floor", 'odd "name" [1]', "gold"]

    picked = MaterialConfig(default="raster", by_id={0: ("glossy", {"samples": 2}), 2: ("reflections", {})},
                            importance_of={"ids.2": 3.0},
                            render={"stereo": "reuse", "denoise": True, "msaa": 4, "temporal": True})
    summary = {"budget_ms": 11.1, "within_budget": True, "measured_ms": 10.2, "measured_flip": 0.05,
               "knobs": FrameKnobs("reuse", 8, True, 4, 1.0, temporal=True, camera="foveated")}
    text = pick_toml(Scene(), summary, picked, (640, 480))
    assert "# capture with: --spp 8 --camera-model foveated" in text
    path = tmp_path / "pick.toml"
    path.write_text(text)
    back = load_config(path)
    names = Scene().material_names()
    assert back.render == {"stereo": "reuse", "denoise": True, "msaa": 4, "temporal": True}
    for a, b in zip(picked.assign(names, warn=False), back.assign(names, warn=False)):
        assert (a.effect, a.params, a.importance) == (b.effect, b.params, b.importance)


def test_cli_refuses_knobs_without_a_budget_or_twice_set(tmp_path):
    cases = [(["--frame-knobs", "stereo=dual,reuse"], "--frame-knobs goes with --budget-ms or --budget-hz"),
             (["--budget-hz", "90", "--frame-knobs", "stereo=dual,reuse", "--stereo", "reuse"], "leave out --stereo"),
             (["--budget-hz", "90", "--frame-knobs", "scale=0.5,1"], "scale is not a knob this command chooses"),
             (["--budget-hz", "90", "--frame-knobs", "stereo=left"], "frame knob stereo"),
             (["--budget-hz", "0"], "--budget-hz"), (["--budget-hz", "90", "--budget-ms", "5"], "not allowed with")]
    for args, says in cases:
        run = run_rayvr("capture", "--size", "16x12", "--out", tmp_path / "o", *args, timeout=120)
        assert run.returncode == 2, (args, run.stderr)
        assert says in run.stderr and "Traceback" not in run.stderr, (args, run.stderr)
        assert len(run.stderr.strip().splitlines()) <= 2, run.stderr
    assert not (tmp_path / "o").exists()


@needs_flip
def test_reference_never_shares_a_variants_seed(gl, monkeypatch):
    """Every render a frame-wide budget pick measures: the reference's seeds (one a half) are its own."""
    from rayvr.quality import budget, frame_budget, measure
    from rayvr.renderer import Renderer

    seeds = []
    real = measure.measure

    def spy(gl_, scene, rig, variant, *a, **k):
        seeds.append((variant.knob, variant.settings.seed))
        return real(gl_, scene, rig, variant, *a, **k)

    for module in (measure, budget):
        monkeypatch.setattr(module, "measure", spy)
    monkeypatch.setattr(measure, "local_measurer", lambda gl_, scene, rig, repeat, pool=None: lambda vs, bar=None: (
        spy(gl_, scene, rig, v, repeat, pool=pool) for v in vs))
    monkeypatch.setattr(budget, "local_measurer", measure.local_measurer)
    from rayvr.frame.cameras.rig import StereoRig

    with Renderer(None, gl=gl) as r:
        rig = StereoRig.for_scene(r.scene, size=(16, 12))
        frame_budget.auto_config(r, rig, 50.0, repeat=1, progress=False, grid=parse_grid("stereo=dual,reuse"))
    reference = [s for knob, s in seeds if knob == "reference"]
    variants = [s for knob, s in seeds if knob != "reference"]
    assert len(reference) == 2 and len(set(reference)) == 2 and variants  # its two halves, a seed each
    assert not set(reference) & set(variants)


def test_points_the_renderer_refuses_are_left_out_with_the_reason(monkeypatch):
    def rungs(gl, scene, rig, ref, base, ppd, effects, repeat, progress, pool, measure_all, knobs):
        if knobs.stereo == "reuse" and knobs.msaa > 1:
            raise ValueError("stereo mode 'reuse' reprojects one sample per pixel")
        return {"raster": (1.0 + knobs.msaa, np.zeros(4))}

    monkeypatch.setattr(fb, "measure_rungs", rungs)
    monkeypatch.setattr(fb, "options_from_rungs", lambda scene, ref, base, r: (r["raster"][0], [], []))
    got, refused = fb.measure_candidates(None, None, None, None, None, 60.0, parse_grid("stereo=dual,reuse;msaa=1,4"))
    assert [c.knobs for c in got] == [FrameKnobs("dual"), FrameKnobs("dual", msaa=4), FrameKnobs("reuse")]
    assert list(refused) == [FrameKnobs("reuse", msaa=4).label] and "one sample per pixel" in refused[
        FrameKnobs("reuse", msaa=4).label]
    with pytest.raises(ValueError, match="no point of the frame-knob grid renders here: stereo=reuse"):
        fb.measure_candidates(None, None, None, None, None, 60.0, parse_grid("stereo=reuse;msaa=4,8"))


def test_a_rung_the_knobs_camera_cannot_render_is_left_out(monkeypatch):
    """Under camera=foveated the budget measures every rung but ssr (screen-space tracing needs the
    pinhole's depth buffer); under the pinhole, every rung."""
    from rayvr.frame.effects import implemented_effects
    from rayvr.quality import budget
    from rayvr.scene.materials import MaterialConfig

    class Scene:
        name = "test"

        def material_names(self):
            return ["a"]

    class Rig:
        camera = "pinhole"

    class Image:
        image = np.zeros((2, 4, 3), np.uint8)

    def measure_all(variants, bar=None):
        for v in variants:
            yield type("M", (), {"gpu_ms": 1.0, "image": Image.image, "passes": {}})()

    monkeypatch.setattr(budget, "judge", lambda fn, *a: type("F", (), {"result": lambda self: 0.0})())
    seen = {}
    for knobs in (FrameKnobs(camera="foveated"), DEFAULT_KNOBS):
        seen[knobs.camera] = list(budget.measure_rungs(None, Scene(), Rig(), Image, MaterialConfig(), 60.0,
                                                       progress=False, measure_all=measure_all, knobs=knobs))
    assert "ssr" in implemented_effects() and seen["pinhole"] == list(implemented_effects())
    assert seen["foveated"] == [e for e in implemented_effects() if e != "ssr"]
