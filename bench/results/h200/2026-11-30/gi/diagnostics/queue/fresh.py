"""H200 diagnostic: fresh Renderers on one context, first render with many samples (Sponza path)."""
import sys, json, os, time
import numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.gl.context import create_context
gl = create_context(None)
cfg = lambda n: parse_config({"default": "path", "params": {"path": {"samples": n, "bounces": 4, "area_samples": 1}}}, "p")
hdr = lambda f: np.concatenate([f.left.aux["hdr"][..., :3], f.right.aux["hdr"][..., :3]], 1).astype(np.float64)
out, prev = [], None
for spec in sys.argv[1:]:  # w,h,per,spp[,spp...]: one fresh Renderer each
    w, h, per, *spps = (int(x) for x in spec.split(","))
    for name, scene, rig in bench_scenes(("sponza",), (w, h), {}):
        with Renderer(scene, cfg(per), gl=gl, settings=RenderSettings(seed=0x5EED0001)) as r:
            for n in spps:
                t = time.time()
                f = r.render(rig, spp=n, aux=("hdr",))
                x = hdr(f)
                row = {"spec": spec, "spp": n, "wall_s": round(time.time() - t, 2), "mean": float(x.mean()),
                       "same_as_prev": None if prev is None or prev.shape != x.shape else bool((prev == x).all()),
                       "rt_path_ms": round(f.timings.get("rt_path", -1), 2), "accumulate_ms": round(f.timings.get("accumulate", -1), 3),
                       "passes": list(f.timings)[:30], "gl_errors": str(gl.gl_errors())}
                prev = x
                print(json.dumps(row), flush=True)
                out.append(row)
json.dump(out, open(os.path.join(os.environ.get("OUT", "/tmp"), "fresh.json"), "w"), indent=1)
