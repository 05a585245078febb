"""Kernel times of the denoiser (Sponza, path 1 spp, 2x1440x1600), median of 20 profiled frames after warm-up."""
import json, os, sys
import numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.gl.context import create_context
gl = create_context(None)
size = tuple(int(x) for x in (sys.argv[1] if len(sys.argv) > 1 else "1440x1600").split("x"))
cfg = parse_config({"default": "path", "params": {"path": {"samples": 1, "bounces": 4, "area_samples": 1}}}, "p")
rows = []
for name, scene, rig in bench_scenes(("sponza", "default"), size, {}):
    with Renderer(scene, cfg, gl=gl, settings=RenderSettings(denoise=True, denoise_iterations=4)) as r:
        r.warm_up(rig)
        runs = []
        for _ in range(20):
            fc = r.record(rig, profile=True)
            runs.append(r.read_ms(fc))
        keys = [k for k in runs[0] if k.startswith(("denoise", "accumulate"))]
        row = {"scene": name, "size": size, **{k: float(np.median([x.get(k, np.nan) for x in runs])) for k in keys}}
        row["denoise_total"] = sum(v for k, v in row.items() if k.startswith("denoise."))
        print(json.dumps(row), flush=True)
        rows.append(row)
json.dump({"device": gl.ctx.info["GL_RENDERER"], "version": gl.ctx.info["GL_VERSION"], "rows": rows},
          open(os.path.join(os.environ.get("OUT", "/tmp"), "denoise_profile.json"), "w"), indent=1)
