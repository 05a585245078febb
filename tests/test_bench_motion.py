"""`rayvr bench motion` (rayvr/bench/motion.py) on a tiny room: one row per trajectory and variant,
each frame judged against its own reference (a variant that renders the references' own settings
scores 0 FLIP and 0 flicker; one sample a pixel does not), and the command's quick run writes its
report."""
from __future__ import annotations

import json

import pytest

pytest.importorskip("flip_evaluator", reason="bench motion scores with FLIP (the bench extra)")

from conftest import run_rayvr  # noqa: E402
from rayvr.bench import motion  # noqa: E402


def test_each_frame_is_judged_against_its_own_reference(tmp_path):
    same = {"spp": 4, "seed": motion.REFERENCE_SEED}  # the references' own settings
    result = motion.run(tmp_path, size=(24, 16), scenes=("default",), kinds=("slow_look", "walk"), rates=(90,),
                        seconds=0.03, variants={"as reference": same, "1 spp": {}}, reference_spp=4, progress=False)
    rows = {(r["trajectory"], r["variant"]): r for r in result["rows"]}
    assert set(rows) == {(k, v) for k in ("slow_look", "walk") for v in ("as reference", "1 spp")}
    for kind in ("slow_look", "walk"):
        ref, raw = rows[kind, "as reference"], rows[kind, "1 spp"]
        assert ref["frames"] == raw["frames"] == 4 and ref["rate_hz"] == 90.0
        assert ref["mean_flip"] == 0.0 and ref["flicker"] == 0.0  # frame k is paired with reference k
        assert raw["mean_flip"] > 0.0 and raw["flicker"] > 0.0 and raw["worst_flip"] >= raw["mean_flip"]
        assert raw["noise_floor_flip"] > 0.0  # two references of different seeds
    assert (tmp_path / "motion.json").exists() and "slow_look" in (tmp_path / "motion.md").read_text()


def test_the_quick_bench_runs_from_the_command_line(tmp_path):
    run = run_rayvr("bench", "motion", "--quick", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr
    rows = json.loads((tmp_path / "motion.json").read_text())["rows"]
    assert {r["trajectory"] for r in rows} == set(motion.KINDS)
    assert {r["rate_hz"] for r in rows} == {90.0, 120.0}
