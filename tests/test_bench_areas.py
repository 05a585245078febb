"""`rayvr bench`: its areas are one table (rayvr/bench/__init__.py AREAS): the command line's choices,
their help and the dispatch all come from it, so an area added there is a command at once."""
from __future__ import annotations

import argparse

from rayvr import bench
from rayvr.cli import build_parser


def _bench_parser(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return commands.choices["bench"]


def _area_argument(parser: argparse.ArgumentParser) -> argparse.Action:
    return next(a for a in _bench_parser(parser)._actions if a.dest == "area")


def test_the_choices_and_their_help_are_the_table():
    area = _area_argument(build_parser())
    assert tuple(area.choices) == tuple(bench.AREAS)
    for name, entry in bench.AREAS.items():
        assert f"{name}: {entry.help}" in area.help


def test_an_area_added_to_the_table_runs_through_the_command(monkeypatch, tmp_path):
    """The command is a lookup: a toy area gets its arguments and the checked output folder."""
    ran = []
    toy = bench.Area("a toy area", lambda args, out, camera_from_args: ran.append((args.area, args.quick, out)))
    monkeypatch.setitem(bench.AREAS, "toy", toy)
    parser = build_parser()
    assert "toy: a toy area" in _area_argument(parser).help
    args = parser.parse_args(["bench", "toy", "--quick", "--out", str(tmp_path / "results")])
    assert args.func(args) == 0
    assert ran == [("toy", True, tmp_path / "results")]


def test_an_area_that_takes_no_workers_refuses_them(monkeypatch, tmp_path):
    """--workers is for the areas the table marks as spreading their variants; the others say so
    in one line (raised before any work)."""
    import pytest

    ran = []
    monkeypatch.setitem(bench.AREAS, "toy", bench.Area("a toy area", lambda *a: ran.append(a)))
    monkeypatch.setattr("rayvr.app.cluster.require_ray", lambda: None)
    args = build_parser().parse_args(["bench", "toy", "--workers", "2", "--out", str(tmp_path)])
    with pytest.raises(ValueError, match="--workers spreads the tradeoff and budget sweeps; bench toy runs in one"):
        args.func(args)
    assert not ran
