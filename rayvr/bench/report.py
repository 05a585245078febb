"""Writing benchmark results: JSON, a markdown table and (optionally) PNG plots.

A result is ``{"meta": {...}, "rows": [{...}, ...]}``. ``meta`` records where and how it was
measured (start from `device_meta`, then add scene, resolution, settings); each row is one
measured point (e.g. one setting of one knob with its ms and error).

JSON is strict: numpy scalars/arrays become plain numbers/lists, +-inf become the strings
``"inf"``/``"-inf"`` (PSNR of identical images) and NaN becomes ``null``, because the JSON
standard has no such numbers. Plots need matplotlib (the ``bench`` extra); without it they are
skipped with a warning and everything else is still written.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import re
import tempfile
import warnings
from importlib import metadata
from pathlib import Path

import numpy as np

# -------------------------------------------------------------------------------------------
# Meta block


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def device_meta(gl_info: dict | None = None) -> dict:
    """The meta block every result records: GL device/driver plus host and package versions.

    `gl_info` is e.g. ``{"vendor": ..., "renderer": ..., "version": ...}`` (moderngl's
    ``ctx.info`` keys ``GL_VENDOR``/``GL_RENDERER``/``GL_VERSION`` work too); each key is stored
    as ``gl_<key>`` in lower case.
    """
    meta: dict = {}
    for k, v in (gl_info or {}).items():
        key = str(k).lower()
        key = key[3:] if key.startswith("gl_") else key
        meta["gl_" + key] = v
    meta.update({
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "moderngl": _version("moderngl"),
        "rayvr": _version("rayvr"),
        "flip_evaluator": _version("flip-evaluator"),
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "commit": source_commit(),
    })
    return meta


def source_commit() -> str | None:
    """The commit of the rayvr source that ran: $RAYVR_COMMIT (a copy of the tree without its git
    folder, as the GPU machine gets, says it so), else git's answer for the package's folder."""
    if os.environ.get("RAYVR_COMMIT"):
        return os.environ["RAYVR_COMMIT"]
    import subprocess

    try:
        run = subprocess.run(["git", "-C", os.path.dirname(os.path.abspath(__file__)), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return (run.stdout.strip() or None) if run.returncode == 0 else None


def provenance(meta: dict) -> str:
    """One line for a figure: device, date and commit of the run it shows."""
    line = (f"{meta.get('gl_renderer', '?')}, {str(meta.get('date', '?'))[:10]}, "
            f"commit {meta.get('commit') or 'unknown'}")
    if meta.get("kept_from"):  # rows earlier runs of the same settings measured (bench tradeoff --knobs)
        line += f"; other rows: commit {', '.join(meta['kept_from'])}"
    return line


# -------------------------------------------------------------------------------------------
# Pareto front


def pareto_front(points) -> list[int]:
    """Indices of the points on the Pareto front when minimising both coordinates.

    `points` is a sequence of (x, y). A point is on the front if no other point has x <= and
    y <= with one of them strictly smaller. Returned sorted by x (so y decreases along it);
    of exact duplicates only the first is kept; points with NaN are ignored.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    idx = np.flatnonzero(~np.isnan(pts).any(axis=1))
    order = idx[np.lexsort((idx, pts[idx, 1], pts[idx, 0]))]  # by x, then y, then input order
    front, best_y = [], math.inf
    for i in order:
        if pts[i, 1] < best_y:
            front.append(int(i))
            best_y = pts[i, 1]
    return front


# -------------------------------------------------------------------------------------------
# Files


def to_jsonable(x):
    """Convert numpy types, tuples, Paths and non-finite floats for strict JSON."""
    if isinstance(x, dict):
        return {str(k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        if math.isnan(v):
            return None
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return v
    if x is None or isinstance(x, str):
        return x
    return str(x)


# -------------------------------------------------------------------------------------------
# What a frame shows


def effect_share(material_maps, names, config) -> dict:
    """{effect: the fraction of the pixels of `material_maps` (each eye's material ids, read back
    from the G-buffer) whose material `config` gives that effect, "background": the pixels that hit
    nothing (ids past the scene's `names`)}: which effects a timed frame spends its pixels on.
    Every effect the config gives a material is a key, 0 where the frame shows none of it."""
    ids = np.concatenate([np.asarray(m).ravel() for m in material_maps])
    counts = np.bincount(np.minimum(ids, len(names)).astype(np.int64), minlength=len(names) + 1)
    out: dict = {}
    for a, n in zip(config.assign(list(names), warn=False), counts[:len(names)]):
        out[a.effect] = out.get(a.effect, 0) + int(n)
    out["background"] = int(counts[len(names)])
    return {k: v / max(ids.size, 1) for k, v in out.items()}


def share_text(share: dict | None) -> str:
    """An effect_share as reports print it, largest first: "shadows 40%, glossy 31%, background 8%"
    (effects the frame does not show left out; "<1%" for a sliver)."""
    if not share:
        return "-"
    parts = [f"{k} {v * 100:.0f}%" if v >= 0.005 else f"{k} <1%"
             for k, v in sorted(share.items(), key=lambda kv: -kv[1]) if v > 0]
    return ", ".join(parts) or "-"


def _atomic_write(path: Path, write) -> None:
    """Write through a temp file in the same folder, then rename: readers (and a crash
    mid-sweep) never see a half-written file."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix="." + path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if math.isinf(v):
            return "∞" if v > 0 else "-∞"
        return "nan" if math.isnan(v) else f"{v:.4g}"
    if isinstance(v, (dict, list, tuple)):
        v = json.dumps(to_jsonable(v))
    # A '|' would split the cell; newlines would end the row.
    return str(v).replace("|", "\\|").replace("\n", " ")


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def markdown(name: str, result: dict) -> str:
    """The markdown text: a title, a warning where the timings are a software rasterizer's, the rows
    as a table, then the run's meta as a list (what a reader looks for first comes first)."""
    meta = result.get("meta", {})
    lines = [f"# {name}", ""]
    if meta.get("timings_meaningful") is False or "llvmpipe" in str(meta.get("gl_renderer", "")):
        lines += [f"**A software rasterizer ({meta.get('gl_renderer', 'no GPU')}): its GL timer queries do not "
                  "measure GPU work; the ms, and whatever is chosen by them, are for correctness only.**", ""]
    rows = result.get("rows", [])
    cols: list[str] = []
    for r in rows:  # union of keys, in first-seen order
        cols += [k for k in r if k not in cols]
    if cols:
        lines.append("| " + " | ".join(_fmt(c) for c in cols) + " |")
        lines.append("|" + "---|" * len(cols))
        for r in rows:
            lines.append("| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
    else:
        lines.append("(no rows)")
    lines += ["", "## The run", ""]
    for k, v in _flatten(meta).items():
        lines.append(f"- **{k}**: {_fmt(v)}")
    return "\n".join(lines) + "\n"


def _check(name: str, result) -> None:
    if not name or not re.fullmatch(r"[A-Za-z0-9._-]+", name) or name.startswith("."):
        raise ValueError(f"report name must be a plain file stem ([A-Za-z0-9._-]), got {name!r}")
    if not isinstance(result, dict) or not isinstance(result.get("meta", {}), dict):
        raise TypeError("result must be a dict with a 'meta' dict and a 'rows' list")
    rows = result.get("rows")
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        raise TypeError("result['rows'] must be a list of dicts")


def earlier_rows(path, meta: dict, same: tuple, keep) -> tuple[list, dict]:
    """The rows r of the report at `path` with keep(r) true, and that report's meta, if it was
    written with this run's `meta` values for the keys `same` (the device, the size, the settings
    its figures depend on); else ([], {}). A bench that measures part of its grid (some scenes,
    some views) keeps the folder's rows of the rest this way: runs split over several device
    calls add up to one report."""
    try:
        old = json.loads(Path(path).read_text())
        om = old["meta"]
        if any(om.get(k) != meta.get(k) for k in same):
            return [], {}
        return [r for r in old["rows"] if keep(r)], om
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return [], {}


def write_report(out_dir, name: str, result: dict, plots: list[dict] | None = None, md: str | None = None) -> dict:
    """Write ``name.json``, ``name.md`` (`md`, or the meta and rows as a table) and the requested
    plots under `out_dir`.

    Each plot spec is ``{"x": col, "y": col, "group": col (optional), "title": str (optional),
    "pareto": bool (optional), "logx"/"logy": bool (optional), "file": stem (optional)}``; the
    file defaults to ``<name>_<y>_vs_<x>.png``. Rows lacking x or y, or with non-finite values,
    are left out of that plot. Returns ``{"json": path, "md": path, "plots": [paths]}``.
    """
    _check(name, result)
    for spec in plots or []:
        if not isinstance(spec, dict) or "x" not in spec or "y" not in spec:
            raise ValueError(f"a plot spec needs 'x' and 'y' columns, got {spec!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = to_jsonable({"meta": result.get("meta", {}), "rows": result["rows"]})
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    paths: dict = {"json": out / f"{name}.json", "md": out / f"{name}.md", "plots": []}
    _atomic_write(paths["json"], lambda f: f.write(text.encode()))
    text_md = markdown(name, result) if md is None else md
    _atomic_write(paths["md"], lambda f: f.write(text_md.encode()))

    if plots:
        try:
            import matplotlib
        except ImportError:
            warnings.warn("plots skipped: matplotlib is missing (pip install rayvr[bench])",
                          stacklevel=2)
        else:
            matplotlib.use("Agg")  # headless: no display on CI or the GPU machine
            for spec in plots:
                paths["plots"].append(_plot(out, name, result["rows"], spec))
    return paths


def _number(v) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _plot(out: Path, name: str, rows: list[dict], spec: dict) -> Path:
    import matplotlib.pyplot as plt

    x, y = spec["x"], spec["y"]
    group = spec.get("group")
    stem = spec.get("file") or f"{name}_{y}_vs_{x}"
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", stem)
    groups: dict = {}
    for r in rows:
        px, py = _number(r.get(x)), _number(r.get(y))
        if px is not None and py is not None:
            groups.setdefault(r.get(group) if group else None, []).append((px, py))

    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    for g, pts in groups.items():
        pts_a = np.array(pts)
        label = None if g is None else f"{group}={g}"
        line = ax.scatter(pts_a[:, 0], pts_a[:, 1], s=18, label=label, alpha=0.8)
        if spec.get("pareto"):
            front = pts_a[pareto_front(pts_a)]
            ax.step(front[:, 0], front[:, 1], where="post", color=line.get_facecolor()[0],
                    linewidth=1.2)
    if spec.get("logx"):
        ax.set_xscale("log")
    if spec.get("logy"):
        ax.set_yscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    title = spec.get("title") or f"{y} vs {x}"
    ax.set_title(title + (" (lines: Pareto front)" if spec.get("pareto") else ""))
    if group and groups:
        ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    path = out / f"{stem}.png"
    _atomic_write(path, lambda f: fig.savefig(f, format="png"))
    plt.close(fig)
    return path
