"""The speed/accuracy machinery end to end at tiny sizes (llvmpipe): sweeps, budget choice."""
import json

import numpy as np
import pytest

from conftest import needs_flip, quick_bench, run_rayvr
from rayvr.quality import metrics
from rayvr.bench import tradeoff as T
from rayvr.frame.cameras.rig import StereoRig
from rayvr.scene.materials import load_config, parse_config
from rayvr.quality.measure import config_for_assignment
from rayvr.scene.loader import load


@pytest.fixture(scope="module")
def room():
    scene = load()
    return scene, StereoRig.for_scene(scene, size=(32, 24))


@needs_flip
def test_sweep_rows_are_the_metrics_of_the_rendered_images(gl, room):
    """run_sweep's reference image and its rows against an independent expectation: the
    reference's two halves rendered again by Renderers of their own (one frame each, no pool, no
    warm-up; the sampled effects are seeded from the settings, so the images are the same), the
    reference the mean of their radiance through the display transform, and the rows' PSNR
    computed here in numpy from those images."""
    scene, rig = room
    from dataclasses import replace

    from rayvr.quality.measure import NOISE_FLOOR_SEED
    from rayvr.quality.reference_images import reference_config
    from rayvr.quality.tonemap import to_ldr
    from rayvr.renderer import Renderer

    ref = T.Variant("reference", "ref", reference_config(scene, quick=True))
    raster = T.Variant("effect", "raster", parse_config({"default": "raster"}))
    rows, measured = T.run_sweep(gl, scene, rig, ref, [raster], metrics.DEFAULT_PPD, repeat=1, progress=False,
                                 per_frame=64)
    floor, row = rows

    def render(variant):
        with Renderer(scene, variant.config, gl=gl, settings=variant.settings) as r:
            frame = r.render(rig, aux=("hdr",))
        return (np.hstack([frame.left.color, frame.right.color]),
                np.hstack([frame.left.aux["hdr"], frame.right.aux["hdr"]]).astype(np.float32))

    def psnr(a, b):
        return 10 * np.log10(255.0 ** 2 / ((a.astype(np.float64) - b.astype(np.float64)) ** 2).mean())

    (half_a, hdr_a), (half_b, hdr_b) = render(ref), render(replace(ref, settings=replace(ref.settings,
                                                                                          seed=NOISE_FLOOR_SEED)))
    raster_image, _ = render(raster)
    want = to_ldr((hdr_a + hdr_b) * 0.5, ref.settings.tonemapper, ref.settings.exposure)
    assert measured.samples == 128 and measured.measured.image.shape == (24, 64, 3)
    assert np.array_equal(measured.measured.image, want)
    assert not np.array_equal(half_a, half_b)  # the halves draw other samples
    assert row["psnr"] == pytest.approx(psnr(want, raster_image), rel=1e-9)  # the reference traces what raster does not
    assert 0.01 < row["flip"] < 1 and row["ssim"] < 1
    # the first row: the reference's halves against each other
    assert floor["knob"] == "noise floor" and floor["reference_spp"] == 128
    assert floor["psnr"] == pytest.approx(psnr(half_a, half_b), rel=1e-9)


@needs_flip
def test_the_noise_floor_falls_as_the_reference_takes_more_samples(gl, room):
    """measure_reference's floor (its halves' FLIP) with 4 frames a half is below the floor with
    1 frame a half: the reference converges, and the floor says by how much."""
    scene, rig = room
    from rayvr.quality.measure import measure_reference
    from rayvr.quality.reference_images import reference_config

    ref = T.Variant("reference", "ref", reference_config(scene, quick=True))
    floors = []
    for samples in (128, 512):
        got = measure_reference(gl, scene, rig, ref, samples, 64)
        assert got.samples == samples
        floors.append(metrics.compare(*(h.image for h in got.halves), metrics=("flip",))["flip"])
    assert floors[1] < 0.8 * floors[0], floors


def test_noise_knobs_are_variants_drawing_other_samples_than_the_reference():
    """The denoiser and accumulated samples join the sweep (`bench tradeoff --quick` below
    renders them; tests/test_accumulate.py shows more samples converge)."""
    base = load_config("rayvr/assets/default_room.toml")
    vs = T.noise_variants(base, quick=True)
    assert [v.label for v in vs] == ["denoise.iterations=0", "denoise.iterations=4", "spp=4", "spp+denoise=4",
                                     "temporal=13"]  # temporal: measure()'s 3 warm-up frames and 10 timed ones
    assert all(v.settings.seed != T.COMPARE_SETTINGS.seed for v in vs)
    assert vs[1].settings.denoise and vs[1].settings.denoise_iterations == 4 and not vs[0].settings.denoise
    assert [v.spp for v in vs] == [1, 1, 4, 4, 1] and vs[3].settings.denoise and vs[4].settings.temporal
    assert len(T.noise_variants(base)) == 11
    # A scene whose config samples nothing gets its noise knobs on a sampled rung.
    scene = load()
    assert T.noisy_base(scene, base) is base
    names = scene.material_names()
    flat = T.noisy_base(scene, parse_config({"default": "raster"}))
    from rayvr.frame.effects import traced_effects

    last_sampled = [e.name for e in traced_effects() if e.denoised][-1]  # photon today
    assert {a.effect for a in flat.assign(names, warn=False)} == {last_sampled}


def test_a_config_that_samples_a_few_materials_gets_the_noise_knobs_again_on_the_sampled_rung_everywhere():
    """The room's config path-traces a few materials, so its spp and denoiser knobs move little of
    the image; the sweep repeats them with every material on path, the frame that converges to the
    reference (the budget mode's best picks are there), under knobs named path_everywhere.*."""
    scene = load()
    names = scene.material_names()
    room = load_config("rayvr/assets/default_room.toml")
    assert T.converging_rung() == "path"
    swept = T.variants(scene, room, quick=True)
    everywhere = [v for v in swept if v.knob.startswith("path_everywhere.")]
    assert [v.label for v in everywhere] == ["path_everywhere.denoise.iterations=0",
                                             "path_everywhere.denoise.iterations=4", "path_everywhere.spp=4",
                                             "path_everywhere.spp+denoise=4", "path_everywhere.temporal=13"]
    for v in everywhere:
        assert {a.effect for a in v.config.assign(names, warn=False)} == {"path"} and v.touches == ()
        assert v.settings.seed == T.NOISE_SEED != T.reference_variant(room).settings.seed
    # the room's own noise knobs stay, on its own config
    assert [v.config for v in swept if v.knob == "spp"] == [room]
    # A config already all on path has them once; one on no sampled rung has its noise knobs on the
    # ladder's last sampled rung (photon) and these too.
    assert not [v for v in T.variants(scene, parse_config({"default": "path"}), quick=True)
                if v.knob.startswith("path_everywhere.")]
    flat = T.variants(scene, parse_config({"default": "raster"}), quick=True)
    assert len([v for v in flat if v.knob.startswith("path_everywhere.")]) == 5
    (spp,) = [v for v in flat if v.knob == "spp"]
    assert {a.effect for a in spp.config.assign(names, warn=False)} == {"photon"}


def test_knobs_select_a_knob_or_its_family_and_an_unknown_name_is_refused():
    scene = load()
    swept = T.variants(scene, load_config("rayvr/assets/default_room.toml"), quick=True)
    got = T.chosen_knobs(swept, ("path_everywhere", "stereo", "path.samples"))
    assert {v.knob for v in got} == {"path_everywhere.denoise.iterations", "path_everywhere.spp",
                                     "path_everywhere.spp+denoise", "path_everywhere.temporal", "stereo",
                                     "path.samples"}
    assert {v.knob for v in T.chosen_knobs(swept, ("path",))} == {k for k in (v.knob for v in swept)
                                                                  if k.startswith("path.")}
    assert T.chosen_knobs(swept, None) == swept
    with pytest.raises(ValueError, match=r"--knobs: pth, spp\+ names no knob here; the knobs: .*path_everywhere\.spp"):
        T.chosen_knobs(swept, ("pth", "stereo", "spp+"))


def test_a_run_of_some_knobs_keeps_the_other_knobs_rows_and_says_from_which_run(tmp_path, monkeypatch):
    """`bench tradeoff --knobs K` into a folder of a full run of the same settings: K's rows and
    the noise floor are new, every other knob's rows stay, and the report (and its plots' title)
    names the commit they came from."""
    measured = []

    def sweep(gl, scene, rig, reference, variants_, *a, **k):
        measured.append([v.knob for v in variants_])
        rows = [{"scene": scene.name, "knob": "noise floor", "value": "", "label": f"floor {len(measured)}",
                 "gpu_ms": 1.0, "flip": 0.1}]
        return rows + [{"scene": scene.name, "knob": v.knob, "value": v.value, "label": f"{v.label} #{len(measured)}",
                        "gpu_ms": 1.0, "flip": 0.5} for v in variants_], None

    monkeypatch.setattr(T, "run_sweep", sweep)
    monkeypatch.setattr(T, "plot_tradeoff", lambda *a, **k: None)
    monkeypatch.setenv("RAYVR_COMMIT", "aaaaaaa")
    first = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=0, progress=False)
    monkeypatch.setenv("RAYVR_COMMIT", "bbbbbbb")
    got = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=0, progress=False,
                knobs=("stereo",))
    assert set(measured[1]) == {"stereo"}
    labels = {r["label"] for r in got["rows"]}
    assert labels == ({r["label"] for r in first["rows"] if r["knob"] not in ("stereo", "noise floor")}
                      | {"floor 2", "stereo=warp #2", "stereo=reuse #2"})
    assert got == json.loads((tmp_path / "tradeoff.json").read_text())
    meta = got["meta"]
    assert "stereo" not in meta["kept_knobs"] and "effect" in meta["kept_knobs"] and meta["knobs"] == ["stereo"]
    assert meta["kept_from"] == ["aaaaaaa"] and meta["commit"] == "bbbbbbb"
    assert {r["commit"] for r in got["rows"] if r["knob"] in ("stereo", "noise floor")} == {"bbbbbbb"}
    assert {r["commit"] for r in got["rows"] if r["knob"] not in ("stereo", "noise floor")} == {"aaaaaaa"}
    from rayvr.bench.report import provenance

    assert provenance(meta).endswith("commit bbbbbbb; other rows: commit aaaaaaa")
    # a third commit sweeps the camera into that folder: both earlier commits are named
    monkeypatch.setenv("RAYVR_COMMIT", "ccccccc")
    got = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=0, progress=False,
                knobs=("camera",))
    assert got["meta"]["kept_from"] == ["aaaaaaa", "bbbbbbb"]
    # a full run keeps nothing of the views it measures
    got = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=0, progress=False)
    assert all(r["label"].endswith("#4") or r["label"] == "floor 4" for r in got["rows"])
    assert "kept_from" not in got["meta"] and got["meta"]["kept_knobs"] == []


def test_swept_parameters_reach_per_material_entries():
    base = parse_config({"materials": {"gold": {"effect": "glossy", "samples": 8}}})
    cfg = T.config_with(base, params={"glossy": {"samples": 2}})
    (gold,) = cfg.assign(["gold"], warn=False)
    assert gold.params["samples"] == 2


def test_assignment_config_keeps_base_params_for_the_same_effect(room):
    scene, _ = room
    base = load_config(None)
    base = parse_config({"materials": {"gold": {"effect": "glossy", "samples": 8}}})
    cfg = config_for_assignment(base, scene, {"gold": "glossy", "mirror": "reflections"})
    got = {n: a for n, a in zip(scene.material_names(), cfg.assign(scene.material_names(), warn=False))}
    assert got["gold"].effect == "glossy" and got["gold"].params["samples"] == 8
    assert got["mirror"].effect == "reflections" and got["floor"].effect == "raster"


@needs_flip
def test_budget_choice_respects_a_generous_and_a_tight_budget(gl, room):
    scene, rig = room
    from rayvr.quality.reference_images import reference_config

    base = load_config(None)
    from rayvr.quality.measure import measure

    ref = measure(gl, scene, rig, T.Variant("reference", "ref", reference_config(scene, quick=True)), repeat=1)
    from rayvr.quality.budget import per_material_options, solve_budget

    base_ms, options, fixed = per_material_options(gl, scene, rig, ref, base, metrics.DEFAULT_PPD, repeat=1,
                                                   progress=False)
    assert base_ms > 0 and options
    for o in options:
        assert {x.effect for x in o.options} >= {"raster", "shadows"}
        raster = next(x for x in o.options if x.effect == "raster")
        assert raster.cost_ms == 0.0

    # A budget of the base frame leaves nothing for traced effects: wherever every traced option was
    # measured to cost something, raster must be chosen (under timer noise on a loaded machine a
    # traced option can read 0 ms, and then it legitimately fits).
    tight = solve_budget(options, budget_ms=base_ms, base_ms=base_ms, fixed=fixed)
    assert tight.feasible and tight.total_ms <= base_ms + 1e-9
    gated = {e for g in fixed if g.cost_ms > 0 for e in g.effects}
    for o in options:
        if all(x.cost_ms > 0 or x.effect in gated for x in o.options if x.effect != "raster"):
            assert tight.assignment[o.name] == "raster", o.name
    generous = solve_budget(options, budget_ms=1e9, base_ms=base_ms, fixed=fixed)
    assert generous.error <= tight.error


@needs_flip
@pytest.mark.parametrize("area", ["tradeoff", "budget"])
def test_bench_quick_writes_json_table_and_pictures(tmp_path, area):
    result = quick_bench(area, tmp_path, timeout=900)
    assert result["rows"] and result["meta"]["gl_renderer"]
    assert (tmp_path / f"{area}.md").exists()
    rows = result["rows"]
    # --quick: budget takes the fixed view and one head pose, tradeoff the fixed view (the same code)
    assert {r["view"] for r in rows} == ({"fixed"} if area == "tradeoff" else {"fixed", "pose 0"})
    if area == "tradeoff":
        assert {r["knob"] for r in rows} >= {"effect", "resolution_scale", "denoise.iterations", "spp", "spp+denoise",
                                             "temporal", "stereo", "msaa", "camera", "traversal", "bvh_build",
                                             "noise floor"}
        for view in ("fixed",):
            mine = [r for r in rows if r["view"] == view]
            (floor,) = [r for r in mine if r["knob"] == "noise floor"]
            assert floor["flip"] > 0  # another seed's reference: noise, never the same image
            # layouts and builds change speed only: their images are the base config's at full size
            (full,) = [r for r in mine if r["label"] == "resolution_scale=1.0"]
            for r in mine:
                if r["knob"] in ("traversal", "bvh_build"):
                    assert r["flip"] == pytest.approx(full["flip"], abs=1e-9), r["label"]
        # what each row's frame shows: the effect knob's rows put every material on its rung
        for r in rows:
            assert sum(r["effect_share"].values()) == pytest.approx(1.0, abs=1e-6), r["label"]
            assert r["view_kind"] == "fixed"
        background = {r["effect_share"]["background"] for r in rows}
        assert len(background) == 1  # one view, one material map
        for r in (r for r in rows if r["knob"] == "effect"):
            assert {k: v for k, v in r["effect_share"].items() if v > 0} == pytest.approx(
                {k: v for k, v in {r["value"]: 1.0 - min(background), "background": min(background)}.items() if v > 0})
        pytest.importorskip("matplotlib")
        assert {p.name for p in tmp_path.glob("*.png")} >= {"tradeoff_default.png"}
    else:
        for row in rows:
            assert row["assignment"] and (row["measured_ms"] > 0)
            assert row["knobs"] and row["grid_points"] == 1
            saved = (tmp_path / f"budget_default{'' if row['view'] == 'fixed' else '_pose0'}_"
                     f"{row['budget_ms']:.4g}ms.toml").read_text()
            assert '[render]\nstereo = "dual"' in saved  # the pick's frame-wide knobs, to save and reuse
            best = row["grid_best"]
            if best is not None:  # the gap is the pick's FLIP above the grid's best that fits
                assert row["optimality_gap"] == pytest.approx(row["measured_flip"] - best["flip"])
        md = (tmp_path / "budget.md").read_text()
        assert "| default | fixed | 11.11 ms (90 Hz) |" in md
        assert "| default | pose 0 (content) | 11.11 ms (90 Hz) |" in md  # the head pose named with its kind
        # the headline names the worst view of the set, and its kind
        worst = max((r for r in rows if r["budget_ms"] == rows[0]["budget_ms"]), key=lambda r: r["measured_flip"])
        label = "fixed" if worst["view"] == "fixed" else f"{worst['view']} ({worst['view_kind']})"
        assert f"| {worst['measured_flip']:.4f} | {label} |" in md
        _check_shares_against_a_readback(rows)
        # budget_options.json is the solver's table: each pick's predicted error is its sum
        table = json.loads((tmp_path / "budget_options.json").read_text())["rows"]
        for row in rows:
            mine = [o for o in table if (o["view"], o["knobs"]) == (row["view"], row["knobs"])]
            assert mine and {o["material"] for o in mine} <= set(row["assignment"])  # those the view sees
            assert all(o["cost_ms"] == 0.0 for o in mine if o["effect"] == "raster")  # the cost over all-raster
            assert row["predicted_error"] == pytest.approx(sum(
                o["importance"] * o["coverage"] * o["error"] for o in mine
                if row["assignment"][o["material"]] == o["effect"]), rel=1e-9)


def _check_shares_against_a_readback(rows) -> None:
    """Each budget row's effect_share: shares adding up to 1, equal to a count of the material ids
    of its view (read back here, the reference's settings) with the pick's assignment."""
    from rayvr.bench.scenes import bench_scenes
    from rayvr.quality.measure import COMPARE_SETTINGS
    from rayvr.renderer import Renderer

    ((_, scene, fixed),) = list(bench_scenes(("default",), (32, 24), {}))
    views = dict(T.views_of("default", scene, fixed, 1, 22))
    names = scene.material_names()
    with Renderer(scene, settings=COMPARE_SETTINGS) as r:
        for row in rows:
            assert sum(row["effect_share"].values()) == pytest.approx(1.0, abs=1e-6)
            f = r.render(views[row["view"]], aux=("material",))
            ids = np.concatenate([f.left.aux["material"].ravel(), f.right.aux["material"].ravel()])
            counted: dict = {}
            for i in ids.tolist():
                effect = row["assignment"].get(names[i]) if i < len(names) else "background"
                counted[effect] = counted.get(effect, 0) + 1
            assert None not in counted  # every material the view shows has its pick
            got = {k: v for k, v in row["effect_share"].items() if v > 0}
            assert got == pytest.approx({k: n / ids.size for k, n in counted.items()}, abs=1e-9), row["view"]


@needs_flip
def test_capture_budget_mode_records_the_choice(tmp_path):
    run = run_rayvr("capture", "--size", "24x16", "--budget-ms", "1e6", "--out", tmp_path, "-q", timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads((tmp_path / "frame_timings.json").read_text())
    pick = summary["budget"]
    assert pick["feasible"] and pick["budget_ms"] == 1e6
    assert set(pick["assignment"]) >= {"mirror", "floor"}
    # With all the time in the world nothing stays on the bottom rung where a better one exists.
    assert pick["assignment"]["mirror"] != "raster"


def test_the_budget_mode_says_when_its_timings_are_a_software_rasterizers(gl, tmp_path):
    """On llvmpipe (CI) the budget's milliseconds are no GPU's: capture says so before it spends
    its time; on a GPU it says nothing of the kind (issue 46 item 3)."""
    run = run_rayvr("capture", "--size", "16x12", "--budget-ms", "1e6", "--out", tmp_path, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    said = "is a software rasterizer: the budget's GPU timings do not measure a GPU here" in run.stdout
    assert said == gl.is_software, run.stdout[:2000]


def test_reference_and_variants_draw_different_samples():
    """A variant that shared the reference's seed would share its noise and score too well
    (16-sample variants beat 32-sample ones): the reference has a seed of its own, nothing else."""
    import dataclasses

    from rayvr.bench.tradeoff import COMPARE_SETTINGS, reference_variant, variants
    from rayvr.scene.materials import parse_config
    from rayvr.scene.loader import load

    scene = load()
    base = parse_config({"default": "shadows"}, "<t>")
    ref = reference_variant(base)
    assert ref.settings.seed != COMPARE_SETTINGS.seed
    assert dataclasses.replace(ref.settings, seed=COMPARE_SETTINGS.seed) == COMPARE_SETTINGS
    assert ref.settings.seed not in {v.settings.seed for v in variants(scene, base, quick=True)}
    from rayvr.quality.measure import NOISE_FLOOR_SEED

    assert NOISE_FLOOR_SEED != ref.settings.seed  # the noise floor is the reference with other samples
    assert NOISE_FLOOR_SEED not in {v.settings.seed for v in variants(scene, base, quick=True)}


def test_a_sweep_cut_short_keeps_the_views_it_finished(tmp_path, monkeypatch):
    """bench tradeoff writes its rows after every view: a run stopped during the second view (a
    device call's time limit) leaves the first view's rows, marked partial."""
    calls = []

    def sweep(gl, scene, rig, *a, **k):
        calls.append(rig)
        if len(calls) == 2:
            raise KeyboardInterrupt  # the run stopped here
        return [{"scene": scene.name, "knob": "effect", "value": "raster", "label": "effect=raster", "gpu_ms": 1.0,
                 "flip": 0.5}], None

    monkeypatch.setattr(T, "run_sweep", sweep)
    with pytest.raises(KeyboardInterrupt):
        T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=1, progress=False)
    got = json.loads((tmp_path / "tradeoff.json").read_text())
    assert got["meta"]["partial"] is True
    assert [(r["view"], r["label"]) for r in got["rows"]] == [("fixed", "effect=raster")]


def labelled_sweeps(monkeypatch) -> list:
    """run_sweep stubbed: one row a view, labelled with the list's first item (set it between runs)."""
    run_label = ["first"]

    def sweep(gl, scene, rig, *a, **k):
        return [{"scene": scene.name, "knob": "effect", "value": "raster", "label": run_label[0], "gpu_ms": 1.0,
                 "flip": 0.5}], None

    monkeypatch.setattr(T, "run_sweep", sweep)
    monkeypatch.setattr(T, "plot_tradeoff", lambda *a, **k: None)
    return run_label


def test_a_run_keeps_the_folders_views_it_does_not_measure(tmp_path, monkeypatch):
    """Runs split over device calls add up: a run of the fixed view leaves the head pose an earlier
    run of the same device and settings measured, and replaces the fixed view; a run with other
    settings keeps nothing."""
    run_label = labelled_sweeps(monkeypatch)
    T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=1, progress=False)
    run_label[0] = "second"
    got = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=0, progress=False)
    on_disk = json.loads((tmp_path / "tradeoff.json").read_text())
    for result in (got, on_disk):
        assert sorted((r["view"], r["label"]) for r in result["rows"]) == [("fixed", "second"), ("pose 0", "first")]
        assert result["meta"]["kept_views"] == ["default pose 0"]
    got = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=0, repeat=3, progress=False)
    assert [(r["view"], r["label"]) for r in got["rows"]] == [("fixed", "second")] and not got["meta"]["kept_views"]


def test_budget_reports_are_kept_only_from_the_same_grid_and_rungs(tmp_path):
    meta = {"gl_renderer": "gpu", "gl_version": "4.3", "per_eye_size": [16, 12], "quick": True, "repeat": 10,
            "ppd": 67.0, "pose_seed": 22, "reference_spp": 64, "grid": ["stereo=dual"], "rungs": "the ladder's effects"}
    rows = [{"scene": "sponza", "view": "fixed", "budget_ms": 11.1}, {"scene": "default", "view": "pose 0"}]
    (tmp_path / "budget.json").write_text(json.dumps({"meta": meta, "rows": rows}))
    assert T._earlier_views(tmp_path, "budget", dict(meta), T.SAME_BUDGET) == rows
    mine = [{"scene": "default", "view": "pose 0", "budget_ms": 8.3}]
    assert T._with_earlier(rows, mine, {("default", "pose 0")}) == [rows[0]] + mine
    for key, other in (("grid", ["stereo=dual,reuse"]), ("rungs", ["raster"]), ("per_eye_size", [32, 24]),
                       ("gl_renderer", "llvmpipe")):
        assert T._earlier_views(tmp_path, "budget", {**meta, key: other}, T.SAME_BUDGET) == [], key
    assert T._earlier_views(tmp_path, "budget_grid", meta, T.SAME_BUDGET) == []  # no such report yet


def test_the_foveated_variant_is_left_out_where_the_config_traces_in_screen_space():
    """ssr marches the pinhole's depth buffer, which the foveated camera has none of: a sweep of
    an ssr config has no camera variant (instead of a run that stops at it)."""
    scene = load()
    assert [v.label for v in T.variants(scene, load_config(None), quick=True) if v.camera] == ["camera=foveated"]
    assert not [v for v in T.variants(scene, parse_config({"default": "ssr"}), quick=True) if v.camera]


def test_the_budget_headline_names_the_floor_the_solvers_gap_and_a_grid_answer():
    """The headline's row for a pick that was the grid's render: its FLIP, the solver's own gap
    beside the answer's, and the view's noise floor, with the sample count in the footnote."""
    row = {"scene": "room", "view": "fixed", "budget_ms": 1000 / 90, "measured_flip": 0.21, "measured_ms": 10.5,
           "within_budget": True, "knobs": "stereo=reuse", "from_grid": True,
           "grid_best": {"flip": 0.21}, "optimality_gap": 0.0, "solver_gap": 0.034, "noise_floor": 0.0712}
    text = T.budget_headline([row], {"gl_renderer": "GPU", "per_eye_size": [1440, 1600], "reference_spp": 2048})
    line = next(l for l in text.splitlines() if l.startswith("| room"))
    assert line.split(" | ")[6:] == ["stereo=reuse (the grid render)", "0.2100", "+0.0000", "+0.0340", "0.0712", "- |"]
    assert "| 0.2100 | 10.50 | yes |" in line and "(2048 samples a pixel in all)" in text


def test_the_budget_plot_legend_names_only_the_knobs_that_differ():
    from rayvr.bench.tradeoff import grid_labels

    labels = ["stereo=dual spp=1 denoise=off msaa=1", "stereo=reuse spp=1 denoise=on msaa=1 iterations=4"]
    assert grid_labels(labels) == ["stereo=dual denoise=off", "stereo=reuse denoise=on iterations=4"]
    assert grid_labels(["stereo=dual"]) == ["stereo=dual"]  # one point: its label, not nothing


@pytest.mark.parametrize("settled_ms, spp, temporal, frames", [(1.0, 1, False, 3 + 10), (80.0, 1, False, 2),
                                                              (20.0, 4, False, 2), (80.0, 1, True, 3 + 10)])
def test_an_image_slower_than_the_bound_is_timed_over_fewer_frames(gl, room, monkeypatch, settled_ms, spp, temporal,
                                                                   frames):
    """On a GPU (the settle's record says how long a frame took) an image costing more than
    SLOW_IMAGE_MS (one 80 ms frame, or four of 20 ms) is timed over SLOW_IMAGE_REPEAT images with no
    warm-up; a fast one, and a temporal one (its image holds every frame), over warm-up + repeat."""
    from dataclasses import replace

    from rayvr.gl.context import GLContext
    from rayvr.quality import measure as M
    from rayvr.renderer import Renderer

    scene, rig = room
    assert M.SLOW_IMAGE_REPEAT == 2 and M.WARMUP_FRAMES == 3 and M.SLOW_IMAGE_MS < 80.0 < 4 * M.SLOW_IMAGE_MS
    monkeypatch.setattr(GLContext, "is_software", property(lambda self: False))  # as on the H200
    monkeypatch.setattr(Renderer, "warm_up", lambda self, *a, **k: {"runs": 10, "settled": True, "last": settled_ms})
    rendered = []
    sequence = Renderer.render_sequence

    def counted(self, rigs, *a, **k):
        rendered.append(len(rigs))
        return sequence(self, rigs, *a, **k)

    monkeypatch.setattr(Renderer, "render_sequence", counted)
    settings = replace(M.COMPARE_SETTINGS, temporal=temporal)
    M.measure(gl, scene, rig, M.Variant("effect", "raster", parse_config({"default": "raster"}), settings, spp=spp),
              repeat=10)
    assert rendered == [frames]


@pytest.mark.parametrize("software", [True, False])
def test_the_temporal_knob_on_a_still_view_is_the_mean_of_as_many_samples_as_its_value(gl, room, monkeypatch,
                                                                                       software):
    """`temporal=N` holds the N frames measure() renders (warm-up and timed), no more and no fewer:
    its image equals N accumulated samples exactly. (The knob once set --temporal without the
    accumulation it implies, and its image was one frame's; the settle's frames, on a GPU, and an
    earlier variant's on the same renderer must not count either.)"""
    from rayvr.gl.context import GLContext
    from rayvr.quality import measure as M
    from rayvr.renderer import Renderer

    scene, rig = room
    if not software:  # as on the H200: a settle that renders frames of the variant first
        monkeypatch.setattr(GLContext, "is_software", property(lambda self: False))
        warm_up = Renderer.warm_up
        monkeypatch.setattr(Renderer, "warm_up", lambda self, r, **k: {
            **warm_up(self, r, min_frames=4), "settled": True, "last": 1.0})
    noisy = [v for v in T.noise_variants(T.everywhere(load_config("rayvr/assets/default_room.toml"), "path"),
                                         quick=True, repeat=2)]
    (temporal,) = [v for v in noisy if v.knob == "temporal"]
    assert temporal.settings.accumulate and temporal.value == M.WARMUP_FRAMES + 2
    with M.RendererPool(gl) as pool:
        first = M.measure(gl, scene, rig, temporal, repeat=2, pool=pool)
        again = M.measure(gl, scene, rig, temporal, repeat=2, pool=pool)  # the same renderer, its history dropped
        one = M.measure(gl, scene, rig, replace_spp(temporal, 1, accumulate=False), repeat=2, pool=pool)
        mean = M.measure(gl, scene, rig, replace_spp(temporal, temporal.value, accumulate=False), repeat=1, pool=pool)
    np.testing.assert_array_equal(first.image, mean.image)
    np.testing.assert_array_equal(again.image, mean.image)
    assert np.abs(one.image.astype(int) - mean.image.astype(int)).mean() > 1.0  # one sample is another image


def replace_spp(variant, spp, **settings):
    """`variant` as `spp` accumulated samples of one frame each (no temporal history)."""
    from dataclasses import replace

    return replace(variant, spp=spp, settings=replace(variant.settings, temporal=False, **settings))


def test_views_name_the_fixed_view_and_head_poses_and_runs_of_some_add_up(tmp_path, monkeypatch):
    """`--only-views fixed,0` / `--only-views 1`: the head pose numbered I is the same pose however many are
    drawn, so a run of pose 1 alone into the folder of a run of the fixed view and pose 0 adds up to
    all three views (a device call's time limit splits the budget run this way)."""
    import argparse

    from rayvr.bench import _views
    from rayvr.commands.bench import _view_names

    assert _view_names("fixed,0,2,0") == ("fixed", "pose 0", "pose 2")
    for bad in ("x", "-1", ",", "pose1"):
        with pytest.raises(argparse.ArgumentTypeError):
            _view_names(bad)
    args = argparse.Namespace(only_views=("pose 2", "fixed"), poses=None, pose_seed=22, quick=False)
    assert _views(args) == {"poses": 3, "pose_seed": 22, "views": ("pose 2", "fixed")}
    assert _views(argparse.Namespace(only_views=("fixed",), poses=None, pose_seed=7, quick=False))["poses"] == 0
    with pytest.raises(ValueError, match="--only-views .* or --poses"):
        _views(argparse.Namespace(only_views=("fixed",), poses=2, pose_seed=22, quick=False))

    scene, rig = load(), StereoRig.for_scene(load(), size=(16, 12))
    every = dict(T.views_of("default", scene, rig, 3, 22))
    some = T.views_of("default", scene, rig, 2, 22, only=("pose 1",))
    assert [v for v, _ in some] == ["pose 1"]
    np.testing.assert_array_equal(some[0][1].pose.position, every["pose 1"].pose.position)
    np.testing.assert_array_equal(some[0][1].pose.rotation, every["pose 1"].pose.rotation)
    assert not np.allclose(every["pose 0"].pose.position, every["pose 1"].pose.position)

    run_label = labelled_sweeps(monkeypatch)
    T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=1, progress=False)
    run_label[0] = "second"
    got = T.run(tmp_path, size=(16, 12), scenes=("default",), quick=True, poses=2, views=("pose 1",), progress=False)
    assert sorted((r["view"], r["label"]) for r in got["rows"]) == [("fixed", "first"), ("pose 0", "first"),
                                                                    ("pose 1", "second")]
    assert got["meta"]["kept_views"] == ["default fixed", "default pose 0"]
