"""`rayvr bench peers`: rayvr against the Python tools people would otherwise use.

pyrender: headless (EGL) frames/s for colour + depth readback at 1280x720 of the same scene and
a matching camera, against rayvr's raster-only capture (one eye, colour + linear depth back in
numpy, pipelined pixel-buffer readback). pyrender runs in a child process: two EGL contexts in
one process would fight over which is current. (Embree vs rayvr rays/s lives in `bench rays`.)
"""
from __future__ import annotations

import math
import multiprocessing as mp
import os
import time
from pathlib import Path

import numpy as np

from ..scene import loader as scene_mod
from ..frame.cameras.rig import StereoRig, orbit
from ..gl.context import create_context
from ..renderer import Renderer
from .report import device_meta, write_report
from .scenes import SCENES, bench_scenes


def _poses(scene, rig, frames):
    """A small orbit around the rig's view so every frame differs (no cached readbacks)."""
    target = rig.pose.position + rig.pose.forward * 2.0
    off = rig.pose.position - target
    return orbit(target, float(np.hypot(off[0], off[2])) or 1.0, float(off[1]), frames,
                 start_deg=float(np.degrees(np.arctan2(off[0], off[2]))))


def rayvr_fps(gl, scene, rig, frames: int, warmup: int = 5) -> dict:
    r = Renderer(scene, gl=gl)
    try:
        poses = _poses(scene, rig, frames + warmup)
        rigs = [StereoRig(**{**rig.__dict__, "pose": p}) for p in poses]
        r.warm_up(rigs[0], eyes="left")
        t0, gpu, n = None, [], 0
        for i, frame in enumerate(r.render_sequence(rigs, eyes="left")):
            assert frame.left.color.shape[:2] == frame.left.depth.shape
            if i == warmup - 1:
                t0 = time.perf_counter()
            elif i >= warmup:
                n += 1
                gpu.append(sum(frame.timings.values()))
        wall = time.perf_counter() - t0
    finally:
        r.release()
    return {"fps": n / wall, "ms_per_frame": 1e3 * wall / n, "gpu_ms_median": float(np.median(gpu))}


def _pyrender_worker(path, pose, fov_y, size, frames, warmup, queue):
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    os.environ.setdefault("PYGLET_HEADLESS", "1")
    try:
        import pyrender
        import trimesh

        tscene = trimesh.load(str(path), force="scene")
        scene = pyrender.Scene.from_trimesh_scene(tscene, ambient_light=(0.1, 0.1, 0.1))
        cam = pyrender.PerspectiveCamera(yfov=math.radians(fov_y), aspectRatio=size[0] / size[1])
        pose_node = scene.add(cam, pose=pose[0])
        scene.add(pyrender.DirectionalLight(intensity=3.0), pose=pose[0])
        r = pyrender.OffscreenRenderer(*size)
        for i in range(warmup):
            scene.set_pose(pose_node, pose[i % len(pose)])
            r.render(scene)
        t0 = time.perf_counter()
        for i in range(frames):
            scene.set_pose(pose_node, pose[(warmup + i) % len(pose)])
            color, depth = r.render(scene)
        wall = time.perf_counter() - t0
        r.delete()
        queue.put({"fps": frames / wall, "ms_per_frame": 1e3 * wall / frames,
                   "color_shape": list(color.shape), "depth_shape": list(depth.shape)})
    except Exception as exc:  # reported, not raised: the peer is optional
        queue.put({"error": f"{type(exc).__name__}: {exc}"})


def pyrender_fps(path, poses, fov_y, size, frames, warmup=5, timeout=600) -> dict:
    mats = []
    for p in poses:
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = p.rotation, p.position
        mats.append(m)
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    proc = ctx.Process(target=_pyrender_worker, args=(str(path), mats, fov_y, size, frames, warmup, q))
    proc.start()
    try:
        return q.get(timeout=timeout)
    except Exception as exc:
        return {"error": f"pyrender did not answer: {exc}"}
    finally:
        proc.join(5)
        if proc.is_alive():
            proc.terminate()


def run(out_dir: Path, size=(1280, 720), scenes=("default", "sponza"), frames=200, backend=None,
        progress=True) -> dict:
    gl = create_context(backend)
    rows, skipped = [], {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            ours = rayvr_fps(gl, scene, rig, frames)
            path = scene.path or scene_mod.DEFAULT_SCENE
            theirs = pyrender_fps(path, _poses(scene, rig, frames + 5), rig.fov_y, size, frames)
            row = {"scene": name, "triangles": scene.triangle_count, "size": f"{size[0]}x{size[1]}",
                   "rayvr_fps": ours["fps"], "rayvr_gpu_ms": ours["gpu_ms_median"],
                   "pyrender_fps": theirs.get("fps"), "pyrender_error": theirs.get("error"),
                   "ratio": (ours["fps"] / theirs["fps"]) if theirs.get("fps") else None}
            rows.append(row)
            if progress:
                ratio = f"{row['ratio']:.2f}x" if row["ratio"] else theirs.get("error")
                print(f"  {name:8s} rayvr {ours['fps']:8.1f} fps   pyrender {theirs.get('fps') or 0:8.1f} fps   {ratio}")
        meta = {**device_meta(gl.info()), "bench": "peers", "frames": frames, "skipped": skipped,
                "what": "colour + depth in numpy per frame, one view; rayvr raster-only, pipelined PBO "
                        "readback; pyrender OffscreenRenderer.render() through EGL in a child process",
                "scenes": {k: v[0] or "built-in default room" for k, v in SCENES.items()}}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "peers", result)
    return result
