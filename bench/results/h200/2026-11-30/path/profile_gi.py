"""Ad-hoc GPU profile: per-kernel ms of path/glossy/photon on room and Sponza (warm)."""
import json, os, sys, time
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer
from rayvr.scene.materials import parse_config
from rayvr.bench.scenes import bench_scenes
from rayvr.bench.rays import time_effect_stages
from rayvr.bench.photon import config as photon_config
import numpy as np

size = tuple(int(x) for x in (sys.argv[1] if len(sys.argv) > 1 else "1440x1600").split("x"))
out = os.environ.get("OUT", "/tmp")
gl = create_context(None)
res = {"info": gl.info()}
def cfgs(name):
    yield "path1", parse_config({"default": "path", "params": {"path": {"samples": 1, "bounces": 4}}}, "p")
    yield "path1_b1", parse_config({"default": "path", "params": {"path": {"samples": 1, "bounces": 1}}}, "p")
    yield "path1_b2", parse_config({"default": "path", "params": {"path": {"samples": 1, "bounces": 2}}}, "p")
    yield "path1_rr1", parse_config({"default": "path", "params": {"path": {"samples": 1, "bounces": 4, "rr_start": 1}}}, "p")
    yield "shadows1", parse_config({"default": "shadows", "params": {"shadows": {"area_samples": 1}}}, "p")
    if name == "default":
        yield "default_room", parse_config(open("rayvr/assets/default_room.toml").read() if False else __import__("tomllib").load(open("rayvr/assets/default_room.toml","rb")), "room")
    for est in ("grid", "grid_heap"):
        yield f"photon512_0.05_{est}", photon_config(name, 512**2, 0.05, est)
for name, scene, rig in bench_scenes(("default", "sponza"), size, {}):
    for label, cfg in cfgs(name):
        t0 = time.time()
        with Renderer(scene, cfg, gl=gl) as r:
            r.warm_up(rig, min_frames=5)
            ms = [r.read_ms(r.record(rig)) for _ in range(10)]
            med = {k: float(np.median([m[k] for m in ms])) for k in ms[0]}
            st = time_effect_stages(r, rig, repeat=3)
        res[f"{name}/{label}"] = {"passes": med, "stages": st, "frame": sum(med.values())}
        print(name, label, f"frame {sum(med.values()):.2f}", {k: round(v, 2) for k, v in med.items() if v > 0.1}, {k: round(v, 2) for k, v in st.items()}, f"wall {time.time()-t0:.0f}s", flush=True)
        json.dump(res, open(f"{out}/profile_gi.json", "w"), indent=1)
gl.release()
