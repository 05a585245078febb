"""Ad-hoc: is Sponza's multi-sample path frame consistent with accumulated 1-sample frames? (H200)"""
import sys, json, os
import numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.quality import metrics
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.gl.context import create_context
gl = create_context(None)
cfg = lambda n: parse_config({"default": "path", "params": {"path": {"samples": n, "bounces": 4}}}, "p")
both = lambda f: np.concatenate([f.left.color, f.right.color], 1)
hdr = lambda f: np.concatenate([f.left.aux["hdr"][..., :3], f.right.aux["hdr"][..., :3]], 1)
res = {}
for size in [(int(a), int(b)) for a, b in (s.split("x") for s in sys.argv[1:])]:
    for name, scene, rig in bench_scenes(("sponza", "default"), size, {}):
        imgs = {}
        for label, n, spp, seed in (("f16a", 16, 1, 11), ("f16a_again", 16, 1, 11), ("f16b", 16, 1, 22), ("acc16a", 1, 16, 11), ("acc16c", 1, 16, 33), ("f1", 1, 1, 11)):
            with Renderer(scene, cfg(n), gl=gl, settings=RenderSettings(seed=seed)) as r:
                f = r.render(rig, spp=spp, aux=("hdr",))
            imgs[label] = (both(f), hdr(f))
        h = {k: v[1] for k, v in imgs.items()}
        out = {"hdr_mean": {k: float(np.nanmean(v)) for k, v in h.items()},
               "nonfinite": {k: int((~np.isfinite(v)).sum()) for k, v in h.items()},
               "max": {k: float(np.nanmax(v)) for k, v in h.items()}}
        pairs = [("f16a", "f16a_again"), ("f16a", "f16b"), ("acc16a", "acc16c"), ("f16b", "acc16c"), ("f16a", "acc16a"), ("f1", "acc16c"), ("f1", "f16b")]
        out["flip"] = {f"{a}~{b}": metrics.flip(imgs[a][0], imgs[b][0]) for a, b in pairs}
        res[f"{name}/{size[0]}x{size[1]}"] = out
        print(name, size, json.dumps(out), flush=True)
json.dump(res, open(os.path.join(os.environ.get("OUT", "/tmp"), "sponza_spp.json"), "w"), indent=1)
gl.release()
