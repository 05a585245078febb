"""`rayvr capture` throughput with the serial path against the writer pool, per PNG level and for
raw NPY colour (issue 24), as a user runs it: one `rayvr capture` process per run.

    python pipeline.py OUT.json

Each run's figures come from the capture's own summary (PREFIX_timings.json "pipeline": the
capture loop's wall time, frames/s, per-frame ms in rendering, read-back and waiting for the
writers) plus the process's wall time and the bytes written. Run from the repository root.
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ASSETS = Path(__file__).resolve().parents[4] / "rayvr" / "assets"
FRAMES = 10
# (name, capture arguments): the serial path at Pillow's old default level first, then the pool
CASES = [
    ("room raster 2x1440x1600", ["--materials", str(ASSETS / "raster.toml"), "--size", "1440x1600"]),
    ("room default_room.toml 2x480x534", ["--materials", str(ASSETS / "default_room.toml"), "--size", "480x534"]),
]
RUNS = [
    ("serial, level 6 (before)", ["--writers", "1", "--png-compression", "6"]),
    ("serial, level 1", ["--writers", "1", "--png-compression", "1"]),
    ("pool, level 6", ["--png-compression", "6"]),
    ("pool, level 1 (default)", []),
    ("pool, level 0", ["--png-compression", "0"]),
    ("pool, npy", ["--format", "npy"]),
]


def run(case_args: list, run_args: list, out: Path) -> dict:
    cmd = [sys.executable, "-m", "rayvr", "capture", "--frames", str(FRAMES), "--out", str(out), "-q",
           *case_args, *run_args]
    start = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - start
    summary = json.loads((out / "frame_timings.json").read_text())
    images = [p for p in out.iterdir() if p.suffix in (".png", ".npy")]
    return {"args": run_args, "process_wall_s": wall, "pipeline": summary["pipeline"],
            "image_bytes_per_frame": sum(p.stat().st_size for p in images) / FRAMES}


def main(out: str) -> None:
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for case, case_args in CASES:
            for k, (name, run_args) in enumerate(RUNS):
                r = run(case_args, run_args, Path(tmp) / f"{len(results)}")
                results.append({"case": case, "run": name, **r, "load_average": os.getloadavg()})
                p = r["pipeline"]
                print(f"{case:34s} {name:26s} {p['frames_per_s']:6.2f} frames/s  "
                      f"{r['image_bytes_per_frame'] / 2**20:6.2f} MiB/frame  {json.dumps(p['ms_per_frame'])}",
                      flush=True)
    Path(out).write_text(json.dumps({
        "machine": {"host": platform.node(), "cpu_count": os.cpu_count(), "gl": "llvmpipe (software)",
                    "note": "2 cores shared with other jobs while measured: see each run's load_average"},
        "frames": FRAMES, "runs": results}, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
