"""Ad-hoc: does a long accumulation (many frames) stay unbiased? Sponza path (H200)."""
import sys, json, os
import numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.quality import metrics
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.gl.context import create_context
gl = create_context(None)
cfg = lambda n: parse_config({"default": "path", "params": {"path": {"samples": n, "bounces": 4, "area_samples": 1}}}, "p")
both = lambda f: np.concatenate([f.left.color, f.right.color], 1)
hdr = lambda f: np.concatenate([f.left.aux["hdr"][..., :3], f.right.aux["hdr"][..., :3]], 1)
plan = [tuple(int(x) for x in s.split(",")) for s in sys.argv[1:]]  # w,h,per,frames
res, base = [], {}
for w, h, per, frames in plan:
    for name, scene, rig in bench_scenes(("sponza",), (w, h), {}):
        with Renderer(scene, cfg(per), gl=gl, settings=RenderSettings(seed=0x5EED0001)) as r:
            f = r.render(rig, spp=frames, aux=("hdr",))
        img, hd = both(f), hdr(f)
        key = (w, h)
        row = {"size": [w, h], "per": per, "frames": frames, "hdr_mean": float(np.nanmean(hd)), "nonfinite": int((~np.isfinite(hd)).sum()),
               "ldr_mean": float(img.mean())}
        if key in base:
            row["flip_vs_first"] = metrics.flip(base[key], img)
        else:
            base[key] = img
        res.append(row)
        print(json.dumps(row), flush=True)
json.dump(res, open(os.path.join(os.environ.get("OUT", "/tmp"), "accum_count.json"), "w"), indent=1)
gl.release()
