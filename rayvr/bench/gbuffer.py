"""`rayvr bench gbuffer`: G-buffer GPU time, one layered stereo pass vs two mono passes.

The G-buffer is two passes: the visibility raster (triangle ID + depth; the layer mode decides
how both eyes are drawn) and the compute resolve that fills the other channels. Each layer mode
renders the same rig; GPU times come from the passes' GL timer queries (median over `repeat`
frames after `warmup`). Only meaningful on a real GPU: llvmpipe's timer queries are not (see
../shared/references/platform-notes.md).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..frame.cameras.rig import StereoRig
from ..gl.context import create_context
from ..renderer import Renderer, RenderSettings
from .report import device_meta, write_report
from .scenes import bench_scenes

def time_gbuffer(renderer: Renderer, rig: StereoRig, repeat: int, warmup: int) -> dict:
    passes = ("visibility", "gbuffer")
    ms = {p: [] for p in passes}
    renderer.warm_up(rig)
    for i in range(warmup + repeat):
        fc = renderer.record(rig, "both", "color")
        t = renderer.read_ms(fc)
        if i >= warmup:
            for p in passes:
                ms[p].append(t[p])
    vis, res = np.asarray(ms["visibility"]), np.asarray(ms["gbuffer"])
    total = vis + res
    return {"visibility_ms": float(np.median(vis)), "resolve_ms": float(np.median(res)),
            "gbuffer_ms_median": float(np.median(total)), "gbuffer_ms_min": float(total.min()),
            "gbuffer_ms_p90": float(np.percentile(total, 90)), "frames": len(total)}


def run(out_dir: Path, size=(1440, 1600), scenes=("default", "sponza"), repeat=50, warmup=5,
        modes=("vertex", "geometry", "multiview", "passes"), backend=None, progress=True) -> dict:
    gl = create_context(backend)
    if not gl.has_extension("GL_OVR_multiview2"):
        modes = tuple(m for m in modes if m != "multiview")
    rows, skipped = [], {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            for mode in modes:
                r = Renderer(scene, gl=gl, settings=RenderSettings(layer_mode=mode))
                res = time_gbuffer(r, rig, repeat, warmup)
                rows.append({"scene": name, "triangles": scene.triangle_count, "mode": mode,
                             "layers": 2, "size": f"2x{size[0]}x{size[1]}", **res})
                if progress:
                    print(f"  {name:8s} {mode:9s} {res['gbuffer_ms_median']:.3f} ms (median of {res['frames']})")
                r.release()
        meta = {**device_meta(gl.info()), "bench": "gbuffer", "per_eye_size": list(size), "repeat": repeat,
                "warmup": warmup, "skipped": skipped,
                "modes": {"vertex": "one instanced draw, gl_Layer from the vertex stage",
                          "geometry": "one draw, geometry shader with 2 invocations picks the layer",
                          "multiview": "one draw, GL_OVR_multiview2 (num_views = 2)",
                          "passes": "two draws, one per eye (mono baseline)"}}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "gbuffer", result)
    return result
