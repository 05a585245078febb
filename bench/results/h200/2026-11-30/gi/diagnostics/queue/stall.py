"""H200 diagnostic: at which spp does a long accumulation stop changing? Sponza path."""
import sys, json, os, time
import numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.gl.context import create_context
gl = create_context(None)
cfg = lambda n: parse_config({"default": "path", "params": {"path": {"samples": n, "bounces": 4, "area_samples": 1}}}, "p")
hdr = lambda f: np.concatenate([f.left.aux["hdr"][..., :3], f.right.aux["hdr"][..., :3]], 1).astype(np.float64)
out = []
for spec in sys.argv[1:]:
    w, h, per, *spps = (int(x) for x in spec.split(","))
    for name, scene, rig in bench_scenes(("sponza",), (w, h), {}):
        with Renderer(scene, cfg(per), gl=gl, settings=RenderSettings(seed=0x5EED0001)) as r:
            prev = None
            for n in spps:
                t = time.time()
                x = hdr(r.render(rig, spp=n, aux=("hdr",)))
                row = {"size": [w, h], "per": per, "spp": n, "wall_s": round(time.time() - t, 2), "mean": float(x.mean()),
                       "maxdiff_prev": None if prev is None else float(np.abs(x - prev).max())}
                prev = x
                print(json.dumps(row), flush=True)
                out.append(row)
json.dump(out, open(os.path.join(os.environ.get("OUT", "/tmp"), "stall.json"), "w"), indent=1)
