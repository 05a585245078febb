"""Issue 23's frames on random head poses per traversal variant: GPU ms per pass and per wavefront kernel.
usage: python3 .gpu/frames.py OUT [variant=layouts ...]   e.g. default=bvh4,bvh2,bvh4 cw=bvh4,cwbvh,cwbvh"""
import json, os, sys, time
from pathlib import Path
import numpy as np
from rayvr.bench.head_poses import draw_poses
from rayvr.bench.rays import hybrid_config, time_frame, time_stages
from rayvr.bench.scenes import bench_scenes
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import load_config, parse_config

out = Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
variants = dict(a.split("=", 1) for a in sys.argv[2:]) or {"default": ""}
size = tuple(int(x) for x in os.environ.get("SIZE", "1440x1600").split("x"))
poses = int(os.environ.get("POSES", "3"))
want = os.environ.get("CONFIGS", "hybrid,room,path4,photon").split(",")
extra = json.loads(os.environ.get("SETTINGS", "{}"))
gl = create_context()
rows = []
asset = lambda f: load_config(Path("rayvr/assets") / f)
for name, scene, rig0 in bench_scenes(os.environ.get("SCENES", "default,sponza").split(","), size, {}):
    cfgs = {"hybrid": hybrid_config(name),
            "path4": parse_config({"default": "raster", "materials": {"*": {"effect": "path", "bounces": 4}}}, "path4")}
    if name == "default":
        cfgs.update(room=asset("default_room.toml"), photon=asset("photon_room.toml"))
    heads = draw_poses(scene, name, poses, 22)
    for cname in [c for c in want if c in cfgs]:
        for vname, lay in variants.items():
            st = dict(primary="rays", **extra, **({"traversal": tuple(lay.split(","))} if lay else {}))
            with Renderer(scene, cfgs[cname], gl=gl, settings=RenderSettings(**st)) as r:
                for head in heads:
                    rig = StereoRig(head.pose, ipd=rig0.ipd, fov_y=rig0.fov_y, near=rig0.near, size=size, camera=rig0.camera)
                    names, med, total = time_frame(r, rig, 10, 3, warmup_s=1.0 if head.index == 0 else 0.3)
                    stages = time_stages(r, rig, os.environ.get('STAGES', 'rt_'))
                    rows.append(dict(scene=name, config=cname, variant=vname, traversal=lay, pose=head.index,
                                     frame_ms=total, pass_ms={k: med[k] for k in names if k in med}, kernel_ms=stages))
                    top = sorted(rows[-1]["pass_ms"].items(), key=lambda kv: -kv[1])[:4]
                    print(f"{name:7s} {cname:7s} {vname:8s} pose {head.index} {total:7.3f} ms  "
                          + ", ".join(f"{k} {v:.2f}" for k, v in top), flush=True)
            (out / "frames.json").write_text(json.dumps(rows, indent=1))
for (s, c, v) in dict.fromkeys((r["scene"], r["config"], r["variant"]) for r in rows):
    f = [r["frame_ms"] for r in rows if (r["scene"], r["config"], r["variant"]) == (s, c, v)]
    print(f"SUMMARY {s:7s} {c:7s} {v:8s} median {np.median(f):7.3f} worst {max(f):7.3f} ms")
