"""Hostile input files and arguments (issue 20, items 9 and 11): each is one line on stderr, a
non-zero exit, no traceback, nothing written, and before any work."""
import os
import time

import pytest

from conftest import run_rayvr


def refused(run, *words):
    """The CLI refused in one line containing `words`, without a traceback."""
    lines = run.stderr.splitlines()
    assert run.returncode != 0 and len(lines) == 1 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert all(w in lines[0] for w in words), lines[0]
    return lines[0]


def capture(tmp_path, *args, timeout=120):
    return run_rayvr("capture", "--size", "16x12", "--out", tmp_path / "out", *args, timeout=timeout)


def fifo(tmp_path):
    p = tmp_path / "pipe.json"
    os.mkfifo(p)
    return p


# ------------------------------------------------------------------ input files


def test_a_sample_file_pixel_beyond_the_largest_image_is_one_line(tmp_path):
    # (100000, 100000) made the dense table 100001 x 100001: an allocation of 224 GiB
    p = tmp_path / "lens.txt"
    p.write_text("0 0 0 0 0 -1\n100000 100000 0 0 0 -1\n")
    run = capture(tmp_path, "--camera-model", "distorted", "--camera-param", f"samples={p}")
    refused(run, f"{p}:2", "(100000, 100000)", "16384x16384")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("flag, what, source", [
    ("--views", "views file", "/dev/zero"), ("--path", "camera path", "/dev/zero"),
    ("--materials", "material config", "/dev/zero"), ("samples", "camera sample file", "/dev/zero"),
    ("--views", "views file", "fifo"), ("samples", "camera sample file", "fifo"),
    ("--path", "camera path", "folder")])
def test_an_input_that_is_not_a_regular_file_is_one_line_at_once(tmp_path, flag, what, source):
    # /dev/zero read for ever (and a FIFO blocked): only regular files are read, and only so much
    p = {"/dev/zero": "/dev/zero", "fifo": fifo(tmp_path) if source == "fifo" else None,
         "folder": tmp_path}[source]
    args = ["--camera-model", "distorted", "--camera-param", f"samples={p}"] if flag == "samples" else [flag, p]
    start = time.monotonic()
    run = capture(tmp_path, *args, timeout=60)
    refused(run, str(p), what, "folder" if source == "folder" else "not a regular file")
    assert time.monotonic() - start < 30
    assert not (tmp_path / "out").exists()


def test_an_input_file_over_its_size_cap_is_refused_before_reading(tmp_path):
    from rayvr.util.inputs import MAX_JSON_BYTES

    p = tmp_path / "huge.json"
    with open(p, "wb") as fh:  # sparse: nothing is written, the size says it all
        fh.truncate(MAX_JSON_BYTES + 1)
    start = time.monotonic()
    run = capture(tmp_path, "--views", p)
    refused(run, str(p), "views file is larger than 256 MiB")
    assert time.monotonic() - start < 30  # not read, let alone parsed


@pytest.mark.parametrize("flag, what", [("--views", "views file"), ("--path", "camera path")])
def test_json_nested_100k_deep_is_one_line(tmp_path, flag, what):
    p = tmp_path / "deep.json"
    p.write_text("[" * 100_000 + "]" * 100_000)
    run = capture(tmp_path, flag, p)
    refused(run, str(p), what, "nested too deeply")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ bench arguments


@pytest.mark.parametrize("area, extra", [("primary", ["--configs", "pinhole", "--counts", "1"]), ("rays", [])])
def test_bench_with_one_repeat_measures_once(tmp_path, area, extra):
    # --repeat 1 became 0 timed frames (repeat // 2): ZeroDivisionError and NoneType
    import json

    run = run_rayvr("bench", area, "--repeat", "1", "--size", "16x12", "--scenes", "default", "--out", tmp_path,
                    "--layouts", "bvh2", "--no-tiles", *extra, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    result = json.loads((tmp_path / f"{area}.json").read_text())
    assert result["meta"]["repeat"] == 1 and result["rows"]


def test_bench_repeat_below_one_is_refused_in_argument_parsing(tmp_path):
    run = run_rayvr("bench", "bvh", "--repeat", "0", "--out", tmp_path / "out")
    refused(run, "--repeat", "from 1")
    assert not (tmp_path / "out").exists()


def test_bench_out_under_a_file_is_refused_before_measuring(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    start = time.monotonic()
    run = run_rayvr("bench", "bvh", "--quick", "--out", tmp_path / "file" / "results")
    refused(run, "file", "not a folder")
    assert run.stdout == "" and time.monotonic() - start < 20  # nothing measured first
    assert (tmp_path / "file").read_text() == "not a folder"


# ------------------------------------------------------------------ one-line hygiene


def test_a_camera_path_at_1e308_is_refused_without_numpy_warnings(tmp_path):
    p = tmp_path / "far.json"
    p.write_text('{"poses": [{"position": [1e308, 0, 0], "target": [0, 0, 0]}]}')
    run = capture(tmp_path, "--path", p)
    refused(run, str(p), "pose 0")
    assert "RuntimeWarning" not in run.stderr


def test_the_sbvh_progress_bar_is_quiet_under_q(tmp_path):
    env_cache = os.environ.get("RAYVR_BVH_CACHE")
    assert env_cache == "off"  # conftest: the build runs (a cached tree would show no bar either way)
    run = capture(tmp_path, "--bvh-build", "sbvh", "--primary", "rays", "-q")
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stderr == "" and run.stdout == ""
    loud = capture(tmp_path, "--bvh-build", "sbvh", "--primary", "rays")  # the bar is there without -q
    assert loud.returncode == 0 and "SBVH build" in loud.stderr


@pytest.mark.parametrize("model", ["wide", "distorted", "foveated", "dof"])
def test_temporal_with_a_camera_it_cannot_reproject_is_one_line(tmp_path, model):
    run = capture(tmp_path, "--temporal", "--frames", "2", "--camera-model", model)
    refused(run, "--temporal", model)
    assert not (tmp_path / "out").exists()


def test_convergence_with_the_wide_camera_is_one_line(tmp_path):
    run = capture(tmp_path, "--convergence", "2", "--camera-model", "wide")
    refused(run, "--convergence", "wide")
    assert not (tmp_path / "out").exists()
