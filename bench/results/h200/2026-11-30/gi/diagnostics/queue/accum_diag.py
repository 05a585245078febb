"""H200 diagnostic: does render(spp=2) equal the mean of samples 0 and 1 rendered alone (Sponza path)?"""
import sys, json, os
import numpy as np
import rayvr.frame.passes.trace_effect as te
from rayvr.bench.scenes import bench_scenes
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.frame.accumulation import sample_seed
from rayvr.gl.context import create_context
gl = create_context(None)
print("max_ssbo", gl.max_ssbo_bytes, "mem", getattr(gl, "memory_bytes", None), flush=True)
cfg = lambda n: parse_config({"default": "path", "params": {"path": {"samples": n, "bounces": 4, "area_samples": 1}}}, "p")
hdr = lambda f: np.concatenate([f.left.aux["hdr"][..., :3], f.right.aux["hdr"][..., :3]], 1).astype(np.float64)
SEED = 0x5EED0001
out = []
for spec in sys.argv[1:]:
    w, h, per, limit = (int(x) for x in spec.split(","))
    te.WAVE_BUFFER_BYTES = limit
    for name, scene, rig in bench_scenes(("sponza",), (w, h), {}):
        with Renderer(scene, cfg(per), gl=gl, settings=RenderSettings(seed=SEED)) as r:
            tiles = r.tiles(rig)
            a1 = r.render(rig, spp=1, aux=("hdr",))
            a2 = r.render(rig, spp=2, aux=("hdr",))
            a4 = r.render(rig, spp=4, aux=("hdr",))
        parts = []
        for k in range(4):
            with Renderer(scene, cfg(per), gl=gl, settings=RenderSettings(seed=sample_seed(SEED, k))) as r:
                parts.append(r.render(rig, spp=1, aux=("hdr",)))
        ps = [hdr(p) for p in parts]
        row = {"spec": spec, "tiles": len(tiles),
               "a1_vs_sample0": float(np.abs(hdr(a1) - ps[0]).max()),
               "a2_vs_mean01": float(np.abs(hdr(a2) - (ps[0] + ps[1]) / 2).max()),
               "a4_vs_mean0123": float(np.abs(hdr(a4) - sum(ps) / 4).max()),
               "a2_vs_a1": float(np.abs(hdr(a2) - hdr(a1)).max()),
               "s1_vs_s0": float(np.abs(ps[1] - ps[0]).max()),
               "means": [float(hdr(x).mean()) for x in (a1, a2, a4)] + [float(p.mean()) for p in ps],
               "rt_path_ms": [round(x.timings.get("rt_path", -1), 2) for x in (a1, a2, a4)] + [round(p.timings.get("rt_path", -1), 2) for p in parts]}
        print(json.dumps(row), flush=True)
        out.append(row)
json.dump(out, open(os.path.join(os.environ.get("OUT", "/tmp"), "accum_diag.json"), "w"), indent=1)
