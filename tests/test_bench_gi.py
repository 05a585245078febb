"""`rayvr bench gi --quick` end to end on llvmpipe (figures come from the GPU machine): every
table written with finite ms and FLIP, the path reference drawn with other seeds than the
variants, more samples and the denoiser giving lower error, `reuse` shading fewer right-eye
pixels, each target judged in gi.md, and a run stopped midway keeping its rows."""
import json
import math
import shutil

import pytest

from conftest import quick_bench, run_rayvr
from rayvr.frame.accumulation import sample_seed


def rows_of(result, part):
    return [r for r in result["rows"] if r["part"] == part]


def finite(*values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    pytest.importorskip("flip_evaluator")
    out = tmp_path_factory.mktemp("gi")
    return out, quick_bench("gi", out)


def test_every_table_is_written_with_finite_ms_and_flip(quick):
    out, result = quick
    photon = rows_of(result, "photon")
    assert {(r["table"], r["estimator"]) for r in photon} == {(1, "kdtree_heap"), (1, "grid_heap"), (2, "grid_heap"),
                                                              (2, "grid")}
    for r in photon:  # the photon map's cost apart from the direct light's shadow rays
        assert finite(r["map_ms"], r["shadow_ms"], r["query_ms"], r["flip"]) and r["map_ms"] > r["query_ms"] > 0
        assert 0 < r["flip"] < 1
    reuse = rows_of(result, "reuse")
    assert {(r["effect"], r["mode"]) for r in reuse} == {(e, m) for e in ("photon", "path") for m in ("dual", "reuse")}
    for r in reuse:
        assert finite(r["frame_ms"], r["left_ms"], r["right_ms"], r["flip_vs_dual_left"], r["flip_vs_dual_right"])
    path = rows_of(result, "path")
    assert {(r["spp"], r["denoise"]) for r in path} == {(s, d) for s in (1, 4, 16) for d in (False, True)}
    for r in path:
        assert finite(r["frame_ms"], r["rt_path_ms"], r["flip"], r["accumulated_ms"], r["accumulated_flip"])
        assert r["bounces"] == 4 and 0 < r["flip"] < 1
        assert (r["denoise_ms"] is not None) == r["denoise"]
    md = (out / "gi.md").read_text()
    for title in ("Table 1: kd-tree vs hash grid", "Table 2: heap vs no heap", "Table 5: separate eyes (dual) vs reuse",
                  "path: 1/4/16 spp"):
        assert title in md
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        assert "Plots skipped: matplotlib is not installed" in md
    else:
        assert (out / "gi_photon_default.png").stat().st_size > 0 and (out / "gi_path_default.png").stat().st_size > 0


def test_path_reference_draws_other_samples_than_the_variants(quick):
    _, result = quick
    m = result["meta"]["parts"]["path"]
    ref = m["reference"]
    assert ref["seed"] != m["seed"] and ref["spp"] >= 64 and ref["frames"] * ref["samples_per_frame"] == ref["spp"]
    # every frame seed the variants draw (the accumulated 16 frames included) is none of the reference's
    variants = {sample_seed(m["seed"], k) for k in range(16)}
    assert len(ref["frame_seeds"]) == ref["frames"] and not variants & set(ref["frame_seeds"])
    assert ref["frame_seeds"] == [sample_seed(ref["seed"], k) for k in range(ref["frames"])]


def test_more_samples_and_the_denoiser_lower_the_error(quick):
    _, result = quick
    by = {(r["spp"], r["denoise"]): r for r in rows_of(result, "path")}
    assert by[16, False]["flip"] < by[4, False]["flip"] < by[1, False]["flip"]
    assert by[16, False]["accumulated_flip"] < by[4, False]["accumulated_flip"] < by[1, False]["accumulated_flip"]
    assert by[1, True]["flip"] < by[1, False]["flip"]  # the denoiser at one sample
    assert by[16, False]["frame_ms"] > by[1, False]["frame_ms"]  # 16 paths a pixel cost more than one
    assert by[1, False]["accumulated_flip"] == by[1, False]["flip"]  # one accumulated frame is the frame


def test_reuse_shades_fewer_right_eye_pixels(quick):
    _, result = quick
    by = {(r["effect"], r["mode"]): r for r in rows_of(result, "reuse")}
    for effect in ("photon", "path"):
        reuse, dual = by[effect, "reuse"], by[effect, "dual"]
        assert reuse["reused_fraction_right"] > 0.5
        assert reuse["flip_vs_dual_left"] == 0 and dual["flip_vs_dual_right"] == 0  # the left eye is dual's
        assert reuse["flip_vs_dual_right"] > 0  # view-dependent shading copied across
        assert dual["flip_vs_dual_converged_right"] == 0 and reuse["converged_spp"] == dual["converged_spp"] > 1
    # accumulated, most of the noise goes: what is left of reuse's error is the error it makes
    path_reuse, path_dual = by["path", "reuse"], by["path", "dual"]
    assert path_reuse["flip_vs_dual_converged_right"] < path_reuse["flip_vs_dual_right"]
    assert path_dual["noise_floor_converged_right"] < path_dual["noise_floor_right"]
    # Its cost is not asserted here: on llvmpipe at 32x24 the right eye's ms (the stereo frame minus
    # the left-eye frame) is within the timers' noise and once came out the other way round; the
    # shares are the H200 bench's figures (bench/results/h200/2026-11-30/gi).


def test_gi_md_judges_each_target(quick):
    from rayvr.bench import gi

    out, _ = quick
    md = (out / "gi.md").read_text()
    section = md.split("## Targets")[1].split("\n## ")[0]
    judged = [l for l in section.splitlines() if l.startswith("| ") and "**" in l]
    assert len(judged) == 4  # reuse x (photon, path), path 1 spp, denoised 1 spp (no 512² cell in --quick)
    assert all("**met**" in l or "**missed**" in l for l in judged)
    # the photon target's row (512², r = 0.05) is judged on the photon map's ms, not the shadow rays'
    cell = {"part": "photon", "scene": "sponza", "photons": 512 ** 2, "radius": 0.05, "table": 2, "estimator": "grid",
            "shadow_ms": 5.0}
    met, missed = gi.targets([{**cell, "map_ms": 2.9}]), gi.targets([{**cell, "map_ms": 3.1}])
    assert "**met**" in met[0][3] and "**missed**" in missed[0][3]


def test_a_stopped_run_keeps_its_rows_and_split_runs_add_up(quick, gl, monkeypatch, tmp_path):
    """A run killed midway (a time limit) leaves the rows it measured; rows of parts it does not
    measure stay from the folder's earlier run."""
    from rayvr.bench import gi, stereo

    src, before = quick
    out = tmp_path / "gi"
    shutil.copytree(src, out)
    calls = []
    real = stereo.mode_rows

    def dies_on_the_second_effect(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("time limit")
        return real(*a, **k)

    monkeypatch.setattr(stereo, "mode_rows", dies_on_the_second_effect)
    with pytest.raises(RuntimeError, match="time limit"):
        gi.run(out, size=(32, 24), scenes=("default",), repeat=1, warmup=1, quick=True, parts=("reuse",), gl=gl,
               progress=False)
    after = json.loads((out / "gi.json").read_text())
    assert [(r["effect"], r["mode"]) for r in rows_of(after, "reuse")] == [("photon", "dual"), ("photon", "reuse")]
    for part in ("photon", "path"):
        assert rows_of(after, part) == rows_of(before, part)
    assert "Table 5" in (out / "gi.md").read_text()


def test_unknown_part_is_one_line():
    run = run_rayvr("bench", "gi", "--configs", "photon,paths", timeout=60)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "photon, reuse, path" in run.stderr and "Traceback" not in run.stderr
