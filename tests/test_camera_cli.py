"""The camera models and sub-rays from the command line and in `rayvr bench primary`."""
import json

import numpy as np
import pytest
from PIL import Image

from test_cli import rayvr


def test_capture_wide_fov_past_180_with_msaa(tmp_path):
    run = rayvr("capture", "--size", "24x16", "--out", str(tmp_path), "--camera-model", "wide", "--fov", "200",
                "--camera-param", "mapping=equidistant", "--camera-param", "fov_x=300", "--msaa", "4", "--timings")
    assert run.returncode == 0, run.stderr
    img = np.asarray(Image.open(tmp_path / "frame_left.png"))
    assert img.shape[:2] == (16, 24) and img.std() > 0
    for name in ("primary_rays", "sample_accumulate", "sample_resolve"):
        assert name in run.stdout


@pytest.mark.parametrize("args, words", [
    (["--fov", "200"], ["fov_y must be in (0, 180) degrees for a planar projection", "(wide)"]),
    (["--camera-model", "dof", "--camera-param", "blur=2"], ["camera parameter 'blur=2'", "aperture, focus"]),
    (["--camera-model", "distorted", "--camera-param", "samples=/nonexistent/lens.txt"],
     ["/nonexistent/lens.txt: cannot read camera sample file"]),
    (["--camera-model", "distorted", "--camera-param", "coefficients=-0.9"], ["folds over"]),
    (["--msaa", "3"], ["--msaa", "unknown sub-ray count 3; allowed: 1, 4, 8, 16, 32"]),  # the options' one style
])
def test_bad_camera_input_is_one_clear_line(tmp_path, args, words):
    run = rayvr("capture", "--out", str(tmp_path / "o"), "--size", "8x8", *args)
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1 and lines[0].startswith("rayvr capture: error: ") and \
        all(w in lines[0] for w in words), run.stdout + run.stderr
    assert not (tmp_path / "o").exists()


def test_info_graph_shows_the_sample_rounds():
    run = rayvr("info", "--graph", "--size", "64x48", "--camera-model", "distorted", "--msaa", "8")
    assert run.returncode == 0, run.stderr
    assert "8 sub-rays per sample, msaa; 3 colour channel sets (distorted camera)" in run.stdout
    assert "msaa_hits" in run.stdout and "frame_hdr" in run.stdout


def test_bench_primary_reports_each_model_and_sub_ray_count(tmp_path):
    from rayvr.bench import primary

    result = primary.run(tmp_path, size=(16, 12), scenes=("default",), repeat=1, warmup=1, counts=(1, 4), ssaa=(),
                         configs=("raster_gbuffer", "distorted_chromatic"), progress=False, suites=("views",),
                         tiles=False)
    rows = {(r["config"], r["sub_rays_per_sample"]): r for r in result["rows"]}
    assert set(rows) == {("raster_gbuffer", 1), ("distorted_chromatic", 1), ("distorted_chromatic", 4)}
    assert rows["distorted_chromatic", 4]["sub_rays"] == 2 * 16 * 12 * 4 * 3  # both eyes, 3 channel sets
    assert rows["raster_gbuffer", 1]["visibility_ms"] >= 0 and "gbuffer" in rows["raster_gbuffer", 1]["pass_ms"]
    assert rows["distorted_chromatic", 4]["rounds"] >= 3  # at least one shading round per channel set
    # recorded without waiting for the count: at least the rounds needed, at most 4 slots per channel set
    assert rows["distorted_chromatic", 4]["rounds"] <= rows["distorted_chromatic", 4]["rounds_recorded_max"] <= 3 * 4
    meta = json.loads((tmp_path / "primary.json").read_text())["meta"]
    assert meta["bench"] == "primary" and meta["gl_renderer"]


def test_bench_primary_table5_rows_are_written_one_by_one(tmp_path, monkeypatch):
    """Table 5's rows in the paper's order, each written (JSON and markdown) as soon as it is
    measured: a run cut short keeps them. Its pinhole rows carry the standalone trace of the
    camera's rays without and with tile culling, which agree."""
    from rayvr.bench import primary

    done, real = [], primary.time_frame

    def cut_after_three(*args, **kwargs):
        if len(done) == 3:
            raise KeyboardInterrupt  # a time limit
        done.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(primary, "time_frame", cut_after_three)
    with pytest.raises(KeyboardInterrupt):
        primary.run(tmp_path, scenes=("default",), repeat=1, warmup=1, suites=("table5",), table5_size=(16, 8),
                    progress=False)
    rows = json.loads((tmp_path / "primary.json").read_text())["rows"]
    assert [(r["config"], r["sub_rays_per_sample"]) for r in rows] == list(primary.TABLE5[:3])
    assert all(r["size"] == "2x16x8" and r["suite"] == "table5" for r in rows)
    assert rows[2]["sub_rays"] == 2 * 16 * 8 * 8 and rows[2]["rounds"] >= 1
    assert rows[1]["tiles_agree"] == 1.0 and rows[1]["trace_rays"] == 2 * 16 * 8
    assert "| pinhole |" in (tmp_path / "primary.md").read_text()


def test_bench_primary_marks_each_target_met_or_missed():
    from rayvr.bench.primary import targets

    def row(scene, config, n, rate=None, vis=1.0, suite="views"):
        return {"suite": suite, "scene": scene, "config": config, "sub_rays_per_sample": n, "shading": "msaa",
                "size": "2x8x8", "sub_grays_s": rate, "visibility_ms": vis, "primary_ms": vis, "rounds": 2,
                "total_ms": vis}
    got = targets([row("room", "raster_gbuffer", 1, vis=1.5), row("room", "pinhole", 1, 4.5),
                   row("room", "pinhole", 4, 9.0, vis=1.4), row("room", "pinhole", 16, 9.9),
                   row("sponza", "raster_gbuffer", 1, vis=2.0), row("sponza", "pinhole", 1, 3.9),
                   row("sponza", "pinhole", 4, 4.0, vis=2.5)])
    verdicts = {k.split(" (")[0].split(":")[0]: v.split(":")[0] for k, v in got.items()}
    assert verdicts == {"coherent primary rays >= 4 GRays/s on every bench view": "MISSED",  # sponza 3.9
                        ">= 10 G sub-rays/s at 16x": "MISSED", "room": "met", "sponza": "MISSED"}


def test_bench_primary_measures_only_the_rows_asked_for(tmp_path):
    run = rayvr("bench", "primary", "--quick", "--configs", "pinhole", "--counts", "4", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr
    rows = json.loads((tmp_path / "primary.json").read_text())["rows"]
    assert [(r["config"], r["sub_rays_per_sample"], r["shading"]) for r in rows] == [("pinhole", 4, "msaa")]
    assert rows[0]["rounds"] >= 1 and rows[0]["sub_rays"] == 2 * 32 * 24 * 4


@pytest.mark.parametrize("args, words", [
    (["--configs", "pinhol"], ["--configs", "'pinhol'", "raster_gbuffer, pinhole"]),
    (["--counts", "4,3"], ["--counts", "1, 4, 8, 16, 32", "'4,3'"]),
])
def test_bench_primary_bad_subset_is_one_clear_line(tmp_path, args, words):
    run = rayvr("bench", "primary", "--quick", "--out", str(tmp_path / "o"), *args)
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1 and all(w in lines[0] for w in words), run.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("model", ["foveated", "wide"])
def test_screen_space_tracing_through_a_camera_that_is_not_a_pinhole_is_one_clear_line(tmp_path, model):
    """ssr marches the pinhole's depth buffer; the other models have none (the quadtree pass is
    left out for them). It used to end in a GraphError traceback."""
    config = tmp_path / "ssr.toml"
    config.write_text('default = "ssr"\n')
    run = rayvr("capture", "--out", str(tmp_path / "o"), "--size", "8x8", "--camera-model", model,
                "--materials", str(config))
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "Traceback" not in run.stderr, run.stderr
    assert f"screen-space tracing (ssr) marches the pinhole's depth buffer, and the {model} camera" in lines[0]
    assert not (tmp_path / "o").exists()
