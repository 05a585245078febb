"""Probe (tools/device/README.md): where the room's headset frame spends its milliseconds, kernel by
kernel and round by round, and whether the CPU's recording starves the GPU.
`python3 tools/device/probe_rounds.py W H [POSES]` prints, for the room (default_room.toml) through
the distorted chromatic camera at 4x MSAA and the pinhole at 1x, on bench vr's head poses (default
0 and 2): the CPU time to record a frame with the GPU idle, the wall time to its finish, the GPU
timer sum; each kernel's ms and dispatches (profiled frames, summed over rounds and by round); and the
same with one wavefront batch (wave_buffer_bytes 2 GiB) to see the batches' share."""
import sys
import time
from collections import defaultdict

import numpy as np

from rayvr.bench import vr
from rayvr.bench.vr import CAMERA_CONFIGS, bench_scenes, draw_poses, materials_config
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer, RenderSettings

size = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (1440, 1600)
pose_ids = [int(x) for x in sys.argv[3].split(",")] if len(sys.argv) > 3 else [0, 2]
gl = create_context(None)
print(gl.info(), flush=True)
(name, scene, view), = list(bench_scenes(["default"], size, {}))
heads = draw_poses(scene, name, 8, vr.POSE_SEED)
mats, _ = materials_config(gl, "room", name, scene, view, 11.1, False)


def walls(r, rig, n=8):
    cpu, wall, gpu = [], [], []
    for _ in range(n):
        gl.ctx.finish()
        t0 = time.perf_counter()
        fc = r.record(rig, "both", "color")
        t1 = time.perf_counter()
        gl.ctx.finish()
        t2 = time.perf_counter()
        cpu.append((t1 - t0) * 1e3)
        wall.append((t2 - t0) * 1e3)
        gpu.append(sum(r.read_ms(fc).values()))
    return float(np.median(cpu)), float(np.median(wall)), float(np.median(gpu))


def kernels(r, rig, n=3):
    per, calls, rounds = defaultdict(list), {}, defaultdict(lambda: defaultdict(float))
    for _ in range(n):
        fc = r.record(rig, "both", "color", profile=True)
        got = r.read_ms(fc)
        names = list(fc.stage_names)
        summed = defaultdict(float)
        for k, v in got.items():
            summed[k] += v
        for k, v in summed.items():
            per[k].append(v)
        counts = defaultdict(int)
        for s in names:
            counts[s.split("#")[0]] += 1
        calls = counts
    return {k: float(np.median(v)) for k, v in per.items()}, calls


def report(tag, r, rig):
    r.warm_up(rig, seconds=1.5, min_frames=3)
    cpu, wall, gpu = walls(r, rig)
    print(f"{tag}: record (GPU idle) {cpu:.2f} ms, record+finish {wall:.2f} ms, GPU timer sum {gpu:.2f} ms", flush=True)
    fc = r.record(rig, "both", "color")
    print(f"{tag}: rounds per pass", {k: [round(x, 3) for x in v] for k, v in r.read_round_ms(fc).items()
                                     if len(v) > 1 and sum(v) > 0.2}, flush=True)
    ms, calls = kernels(r, rig)
    total = sum(ms.values())
    top = sorted(ms.items(), key=lambda kv: -kv[1])[:40]
    print(f"{tag}: profiled sum {total:.2f} ms; kernels (ms, dispatches):", flush=True)
    for k, v in top:
        print(f"    {k:40s} {v:8.3f} {calls.get(k, '?')}")


for pid in pose_ids:
    head = heads[pid]
    for camera, msaa in (("distorted_chromatic", 4), ("pinhole", 1)):
        model, fov, primary = CAMERA_CONFIGS[camera]
        rig = StereoRig(head.pose, ipd=view.ipd, fov_y=fov or view.fov_y, near=view.near, size=size, camera=model)
        for label, wave in (("", None), (" one batch", 2 << 30)):
            if wave and camera == "pinhole":
                continue
            with Renderer(scene, gl=gl, wave_buffer_bytes=wave) as r:
                r.set_materials(mats)
                r.settings = RenderSettings(primary=primary, msaa=msaa)
                report(f"pose {pid} ({head.kind}) {camera} {msaa}x{label}", r, rig)
