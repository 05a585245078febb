"""Ad-hoc: path / photon / glossy frame ms per traversal layout choice (warm, H200)."""
import json, os, sys, time
from dataclasses import replace
import numpy as np
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config
from rayvr.bench.scenes import bench_scenes
from rayvr.bench.rays import time_effect_stages
from rayvr.bench.photon import config as photon_config
import tomllib
size = tuple(int(x) for x in (sys.argv[1] if len(sys.argv) > 1 else "1440x1600").split("x"))
out = os.environ.get("OUT", "/tmp")
gl = create_context(None)
res = {"info": gl.info()}
path = parse_config({"default": "path", "params": {"path": {"samples": 1, "bounces": 4}}}, "p")
room = parse_config(tomllib.load(open("rayvr/assets/default_room.toml", "rb")), "room")
for name, scene, rig in bench_scenes(("default", "sponza"), size, {}):
    cases = [("path", path), ("photon", photon_config(name, 512**2, 0.05, "grid"))] + ([("room", room)] if name == "default" else [])
    for label, cfg in cases:
        for trav in ("primary=bvh4,shadow=bvh2,reflect=bvh4", "shadow=bvh4", "shadow=bvh8,reflect=bvh8", "reflect=bvh2", "shadow=bvh4,reflect=bvh8"):
            with Renderer(scene, cfg, gl=gl, settings=RenderSettings(traversal=trav)) as r:
                r.warm_up(rig, min_frames=5)
                ms = [r.read_ms(r.record(rig)) for _ in range(10)]
                med = {k: float(np.median([m[k] for m in ms])) for k in ms[0]}
                st = time_effect_stages(r, rig, repeat=3)
            res[f"{name}/{label}/{trav}"] = {"passes": med, "stages": st, "frame": sum(med.values())}
            print(name, label, trav, f"frame {sum(med.values()):.2f}", {k: round(v, 2) for k, v in med.items() if v > 0.1 and k not in ('visibility','gbuffer')}, {k.split('.')[1]: round(v, 2) for k, v in st.items() if v > 0.1}, flush=True)
            json.dump(res, open(f"{out}/path_layouts.json", "w"), indent=1)
gl.release()
