"""`rayvr bench workers`: frames/s of a capture path in one process and over 1, 2, ... Ray workers.

Each run is the whole capture users get: render, read back, encode and write the PNGs of both
eyes, frame after frame. The single-process run is `run_capture` (frame N read back while N+1
renders); the worker runs are `rayvr capture --workers N` (rayvr.app.cluster), timed after every worker
has loaded the scene, and warmed up on a short path first, as the single-process renderer is. The
result says frames/s and ms per frame for each, the scaling of N workers against one, and the
cost of going through Ray (one worker against the single process).
"""
from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from ..app.capture import CaptureJob, poses_for, run_capture
from ..app.cluster import DEFAULT_CONNECT_TIMEOUT_S
from .report import device_meta, write_report
from .scenes import bench_scenes


def _job(rig, poses, out: Path) -> CaptureJob:
    return CaptureJob(rig, poses, out_dir=out)


def _single_process(scene, config, rig, poses, warm, tmp: Path, backend) -> dict:
    from ..renderer import Renderer

    with Renderer(scene, config, backend=backend) as r:
        run_capture(r, _job(rig, warm, tmp / "warm"), progress=False)
        r.warm_up(rig)
        t0 = time.perf_counter()
        summary = run_capture(r, _job(rig, poses, tmp / "single"), progress=False)
        wall = time.perf_counter() - t0
        gl = r.gl.info()["renderer"]
    return {"seconds": wall, "gl": gl, "gpu_ms_mean": sum(summary["gpu_ms_mean"].values())}


def _on_workers(n, spec, rig, poses, warm, tmp: Path, address, connect_timeout) -> dict:
    from ..app.cluster import Cluster, run_capture_distributed

    t0 = time.perf_counter()
    with Cluster(n, spec, address, connect_timeout) as cluster:
        where = cluster.ready()  # scene loaded in every worker
        startup = time.perf_counter() - t0
        run_capture_distributed(cluster, _job(rig, warm * n, tmp / f"warm{n}"), progress=False, chunk=len(warm))
        t0 = time.perf_counter()
        summary = run_capture_distributed(cluster, _job(rig, poses, tmp / f"workers{n}"), progress=False)
        wall = time.perf_counter() - t0
    return {"seconds": wall, "startup_s": startup, "workers_at": where, "gl": summary["gl"],
            "failed": summary["failed"], "retried": summary["retried"],
            "gpu_ms_mean": sum(summary["gpu_ms_mean"].values())}


def run(out_dir, size=(1440, 1600), scenes=("sponza",), frames=64, workers=(1, 2), address=None, backend=None,
        base_config=None, progress=True, connect_timeout=DEFAULT_CONNECT_TIMEOUT_S) -> dict:
    """Time the same capture path in one process and on each worker count; write workers.json/.md."""
    from ..app.cluster import WorkerSpec, require_ray
    from ..util.output import ensure_writable_dir
    from ..renderer import RenderSettings

    require_ray()
    ensure_writable_dir(out_dir)
    rows, skipped, gl_info = [], {}, None
    for name, scene, rig in bench_scenes(scenes, size, skipped):
        config = base_config(name) if base_config else None
        poses = poses_for(rig, scene, frames)
        warm = poses[:4]
        spec = WorkerSpec(None if name == "default" else str(scene.path), None if config is None else str(config),
                          RenderSettings(), backend)
        tmp = Path(tempfile.mkdtemp(prefix="bench_workers_", dir=out_dir))
        try:
            single = _single_process(scene, config, rig, poses, warm, tmp, backend)
            gl_info = gl_info or single["gl"]
            base = {"scene": name, "triangles": scene.triangle_count, "size": f"2x{size[0]}x{size[1]}", "frames": frames}
            rows.append({**base, "mode": "single process", "workers": 0, "fps": frames / single["seconds"],
                         "ms_per_frame": 1e3 * single["seconds"] / frames, "gpu_ms_per_frame": single["gpu_ms_mean"]})
            if progress:
                print(f"  {name:8s} single process  {rows[-1]['fps']:7.2f} frames/s")
            one = None
            for n in workers:
                r = _on_workers(n, spec, rig, poses, warm, tmp, address, connect_timeout)
                shutil.rmtree(tmp / f"workers{n}", ignore_errors=True)  # keep the disk free for the next run
                fps = frames / r["seconds"]
                one = fps if n == 1 else one
                rows.append({**base, "mode": "ray workers", "workers": n, "fps": fps,
                             "ms_per_frame": 1e3 * r["seconds"] / frames, "gpu_ms_per_frame": r["gpu_ms_mean"],
                             "scaling_vs_1_worker": fps / one if one else None,
                             "vs_single_process": fps * single["seconds"] / frames,
                             "startup_s": r["startup_s"], "retried": r["retried"], "failed": r["failed"],
                             "devices": [f"{w['host']}: EGL {w['egl_device']}, CUDA_VISIBLE_DEVICES="
                                         f"{w['cuda_visible_devices']}, {w['gl']}" for w in r["workers_at"]]})
                if progress:
                    print(f"  {name:8s} {n} worker(s)     {fps:7.2f} frames/s "
                          f"(x{rows[-1]['vs_single_process']:.2f} of one process)")
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    meta = {**device_meta({"renderer": gl_info}), "bench": "workers", "per_eye_size": list(size), "frames": frames,
            "workers": list(workers), "address": address, "skipped": skipped,
            "what": "wall time of a whole capture (render, read back, encode and write both eyes' PNGs) of an "
                    "orbit path; workers timed after they loaded the scene and rendered a short warm-up path; "
                    "scaling_vs_1_worker = frames/s of N workers over 1 worker"}
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "workers", result)
    return result
