"""Experiment: where the primary trace's time goes (H200). Variants set RAYVR_PRIMARY_DEFINES (uncommitted hooks)."""
import json, os, sys, time
import numpy as np
from rayvr.bench.scenes import load_bench_scene
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Pinhole, Distorted
from rayvr.renderer import Renderer, RenderSettings
from rayvr.gl.context import create_context
from rayvr.bench.report import device_meta

out = sys.argv[1]
size = tuple(int(x) for x in os.environ.get("SIZE", "1440x1600").split("x"))
gl = create_context()
rng = np.random.default_rng(11)
VARIANTS = [("entries", dict(tile_culling=True, tile_lists=0), "", "64"),
            ("lists256", dict(tile_culling=True, tile_lists=256), "", "64"),
            ("lists256_g256", dict(tile_culling=True, tile_lists=256), "", "256"),
            ("lists256_noedges", dict(tile_culling=True, tile_lists=256), "LIST_NO_EDGES", "64"),
            ("lists512", dict(tile_culling=True, tile_lists=512), "", "64")]
CAMS = [("pinhole", Pinhole(), 1), ("pinhole", Pinhole(), 4), ("pinhole", Pinhole(), 16), ("pinhole", Pinhole(), 32),
        ("distorted_chromatic", Distorted(), 16)]
rows = []
t0 = time.time()
for name in ("sponza", "default"):
    scene, pose = load_bench_scene(name)
    lo, hi = scene.bounds
    poses = [pose] if pose is not None else []
    while len(poses) < 2:
        c = lo + (hi - lo) * np.array([0.25 + 0.5 * rng.random(), 0.3, 0.25 + 0.5 * rng.random()])
        yaw = rng.uniform(0, 2 * np.pi)
        poses.append(Pose.look_at(c, c + np.array([np.sin(yaw), 0.0, np.cos(yaw)])))
    for vname, kw, defines, group in VARIANTS:
        os.environ["RAYVR_PRIMARY_DEFINES"] = defines
        os.environ["RAYVR_LIST_MSAA_GROUP"] = group
        with Renderer(scene, gl=gl) as r:
            for pi, ps in enumerate(poses):
                for cname, cam, n in CAMS:
                    rig = StereoRig.for_scene(scene, size=size, camera=cam)
                    if n == 32 and "512" in vname: continue
                    rig.pose = ps
                    r.settings = RenderSettings(primary="rays", msaa=n, **kw)
                    r.warm_up(rig, seconds=0.3, min_frames=3)
                    ms = {}
                    for _ in range(5):
                        fc = r.record(rig, "both", "color", profile=True)
                        for k, v in r.read_ms(fc).items():
                            ms.setdefault(k, []).append(v)
                    st = {k: float(np.median(v)) for k, v in ms.items() if k.startswith("primary_rays")}
                    row = dict(scene=name, pose=pi, camera=cname, msaa=n, variant=vname, stages=st)
                    if kw.get("tile_lists"):
                        w = np.frombuffer(r.resource("tile_tris").read(), np.uint32).reshape(-1, 2 * (kw["tile_lists"] + 1))[:, 0]
                        row["overflow_share"] = float((w == 0xFFFFFFFF).mean())
                        ok = w[w != 0xFFFFFFFF]
                        row["list_mean"] = float(ok.mean()) if len(ok) else 0.0
                    rows.append(row)
                    print(f"{time.time()-t0:6.1f}s {name} p{pi} {cname} {n}x {vname}:", {k.split('.')[1]: round(v, 3) for k, v in st.items()}, row.get("overflow_share"), row.get("list_mean"), flush=True)
                    json.dump({"device": device_meta(gl.info()), "size": size, "rows": rows}, open(out, "w"), indent=1)
os.environ["RAYVR_PRIMARY_DEFINES"] = ""
os.environ["RAYVR_LIST_MSAA_GROUP"] = "64"
for name in ("sponza",):
    scene, pose = load_bench_scene(name)
    with Renderer(scene, gl=gl) as r:
        for cam, n in ((Pinhole(), 16), (Distorted(), 1)):
            rig = StereoRig.for_scene(scene, size=size, camera=cam); rig.pose = pose
            res = {}
            for vname, kw in (("root", dict(tile_culling=False)), ("entries", dict(tile_culling=True, tile_lists=0)), ("lists", dict(tile_culling=True, tile_lists=256))):
                r.settings = RenderSettings(primary="rays", msaa=n, **kw)
                f = r.render(rig, aux=("triangle",))
                res[vname] = (np.stack([f.left.aux["triangle"], f.right.aux["triangle"]]), np.stack([f.left.color, f.right.color]))
            for k in ("entries", "lists"):
                print(type(cam).__name__, n, k, "triangles differ at", int((res[k][0] != res["root"][0]).sum()), "colour at", int((res[k][1] != res["root"][1]).any(-1).sum()), flush=True)
