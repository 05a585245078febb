import json
import math

import numpy as np
import pytest

from rayvr.bench.report import device_meta, markdown, pareto_front, to_jsonable, write_report


def _result():
    rows = []
    for effect, ms, flip in [("raster", 0.8, 0.20), ("ssr", 1.4, 0.12), ("rt1", 2.9, 0.05),
                             ("rt2", 3.5, 0.06), ("path", 9.0, 0.0)]:
        rows.append({"effect": effect, "stereo": "dual", "ms": ms, "flip": flip,
                     "psnr": math.inf if flip == 0 else 30 - 50 * flip})
    rows.append({"effect": "rt1", "stereo": "warp", "ms": np.float32(1.9), "flip": np.float64(0.07),
                 "psnr": 28.0, "note": "a|b"})
    meta = device_meta({"vendor": "Mesa", "renderer": "llvmpipe", "version": "4.5"})
    meta.update({"scene": "cornell_box", "resolution": [64, 48], "settings": {"bounces": 2}})
    return {"meta": meta, "rows": rows}


def test_pareto_front():
    pts = [(1, 5), (2, 3), (3, 4), (2, 3), (4, 1), (5, 1), (0.5, 9), (np.nan, 0)]
    # (3,4) is dominated by (2,3); (5,1) by (4,1); the duplicate (2,3) is kept once; NaN ignored.
    assert pareto_front(pts) == [6, 0, 1, 4]
    assert pareto_front([]) == []
    assert pareto_front([(1, 1)]) == [0]


def test_device_meta():
    m = device_meta({"GL_RENDERER": "NVIDIA H100", "vendor": "NVIDIA"})
    assert m["gl_renderer"] == "NVIDIA H100" and m["gl_vendor"] == "NVIDIA"
    for key in ("platform", "cpu_count", "python", "numpy", "moderngl", "date"):
        assert key in m
    assert m["numpy"] == np.__version__
    json.dumps(to_jsonable(m), allow_nan=False)


def test_jsonable():
    out = to_jsonable({"a": np.arange(3), "b": (np.float32(1.5), math.inf, -math.inf, math.nan),
                       "c": np.bool_(True), 1: None})
    assert out == {"a": [0, 1, 2], "b": [1.5, "inf", "-inf", None], "c": True, "1": None}


def test_write_json_and_markdown(tmp_path):
    res = _result()
    paths = write_report(tmp_path / "out", "tradeoff", res)
    data = json.loads(paths["json"].read_text())  # strict JSON: no Infinity/NaN tokens
    assert "Infinity" not in paths["json"].read_text()
    assert data["meta"]["scene"] == "cornell_box"
    assert data["meta"]["gl_renderer"] == "llvmpipe"
    assert len(data["rows"]) == 6 and data["rows"][4]["psnr"] == "inf"
    assert data["rows"][5]["ms"] == pytest.approx(1.9)

    md = paths["md"].read_text()
    lines = md.splitlines()
    assert lines[0] == "# tradeoff"
    # llvmpipe's timings are said to be no GPU's before anything else; the table before the meta
    assert lines[2].startswith("**A software rasterizer (llvmpipe)")
    assert lines.index("## The run") > max(i for i, ln in enumerate(lines) if ln.startswith("|"))
    assert "- **scene**: cornell_box" in lines
    assert "- **settings.bounces**: 2" in lines
    table = [ln for ln in lines if ln.startswith("|")]
    assert table[0] == "| effect | stereo | ms | flip | psnr | note |"
    assert table[1] == "|---|---|---|---|---|---|"
    assert len(table) == 2 + 6
    # Every row has the same number of cells; '|' inside a value is escaped.
    assert all(ln.replace("\\|", "").count("|") == 7 for ln in table)
    assert "a\\|b" in table[-1] and "∞" in table[6]
    # No temp files left behind.
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["tradeoff.json", "tradeoff.md"]


def test_markdown_without_rows():
    assert "(no rows)" in markdown("empty", {"meta": {}, "rows": []})


def test_rewrite_replaces(tmp_path):
    write_report(tmp_path, "r", {"meta": {}, "rows": [{"x": 1}]})
    write_report(tmp_path, "r", {"meta": {}, "rows": [{"x": 2}]})
    assert json.loads((tmp_path / "r.json").read_text())["rows"] == [{"x": 2}]


def test_validation(tmp_path):
    with pytest.raises(ValueError, match="file stem"):
        write_report(tmp_path, "../evil", {"meta": {}, "rows": []})
    with pytest.raises(TypeError, match="rows"):
        write_report(tmp_path, "r", {"meta": {}, "rows": [1, 2]})
    with pytest.raises(ValueError, match="plot spec"):
        write_report(tmp_path, "r", {"meta": {}, "rows": []}, plots=[{"x": "ms"}])
    assert not list(tmp_path.iterdir())


def test_plots(tmp_path):
    pytest.importorskip("matplotlib")
    plots = [
        {"x": "ms", "y": "flip", "group": "stereo", "title": "FLIP vs ms", "pareto": True},
        {"x": "ms", "y": "psnr", "file": "psnr plot"},  # inf PSNR is left out of the plot
    ]
    paths = write_report(tmp_path, "tradeoff", _result(), plots=plots)
    assert [p.name for p in paths["plots"]] == ["tradeoff_flip_vs_ms.png", "psnr_plot.png"]
    for p in paths["plots"]:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert p.stat().st_size > 1000


def test_plots_skipped_without_matplotlib(tmp_path, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError("no module")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.warns(UserWarning, match=r"rayvr\[bench\]"):
        paths = write_report(tmp_path, "r", _result(), plots=[{"x": "ms", "y": "flip"}])
    assert paths["plots"] == [] and paths["json"].exists() and paths["md"].exists()


def test_results_name_the_commit_that_made_them(monkeypatch):
    from rayvr.bench import report

    monkeypatch.setenv("RAYVR_COMMIT", "abc1234")
    meta = report.device_meta({"GL_RENDERER": "NVIDIA H200"})
    assert meta["commit"] == "abc1234"
    assert report.provenance(meta) == f"NVIDIA H200, {meta['date'][:10]}, commit abc1234"
    monkeypatch.delenv("RAYVR_COMMIT")
    import subprocess

    here = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                          cwd=report.__file__.rsplit("/", 1)[0])
    assert report.source_commit() == (here.stdout.strip() if here.returncode == 0 else None)
