"""H200 diagnostic: which fresh Renderer's first long render comes back stale (Sponza path)?"""
import sys, json, os, time, gc
import numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.gl.context import create_context
gl = create_context(None)
cfg = lambda n: parse_config({"default": "path", "params": {"path": {"samples": n, "bounces": 4, "area_samples": 1}}}, "p")
hdr = lambda f: np.concatenate([f.left.aux["hdr"][..., :3], f.right.aux["hdr"][..., :3]], 1).astype(np.float64)
out, prev = [], None
for spec in sys.argv[1:]:  # w,h,per,spp[:finish|:gc]: one fresh Renderer each
    spec, _, flag = spec.partition(":")
    w, h, per, n = (int(x) for x in spec.split(","))
    if flag == "finish":
        gl.ctx.finish()
    if flag == "gc":
        gc.collect()
    for name, scene, rig in bench_scenes(("sponza",), (w, h), {}):
        with Renderer(scene, cfg(per), gl=gl, settings=RenderSettings(seed=0x5EED0001)) as r:
            stamps = []
            t = time.time()
            f = r.render(rig, spp=n, aux=("hdr",), progress=lambda k: stamps.append(time.time() - t))
            x = hdr(f)
        row = {"spec": spec, "flag": flag, "wall_s": round(time.time() - t, 2), "mean": float(x.mean()),
               "same_as_prev": None if prev is None or prev.shape != x.shape else bool((prev == x).all()),
               "rt_path_ms": round(f.timings.get("rt_path", -1), 2), "timings": {k: round(v, 3) for k, v in f.timings.items()},
               "record_stamps": [round(s, 2) for s in stamps]}
        prev = x
        print(json.dumps(row), flush=True)
        out.append(row)
json.dump(out, open(os.path.join(os.environ.get("OUT", "/tmp"), "fresh2.json"), "w"), indent=1)
