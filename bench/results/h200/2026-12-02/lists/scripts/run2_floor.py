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
VARIANTS = [("root", dict(tile_culling=False), ""), ("skip", dict(tile_culling=False), "PRIMARY_SKIP_TRACE"),
            ("entries", dict(tile_culling=True, tile_lists=0), ""), ("lists", dict(tile_culling=True, tile_lists=256), ""),
            ("lists_noedges", dict(tile_culling=True, tile_lists=256), "LIST_NO_EDGES"),
            ("lists_nofallback", dict(tile_culling=True, tile_lists=256), "LIST_NO_FALLBACK")]
CAMS = [("pinhole", Pinhole(), 1), ("pinhole", Pinhole(), 16)]
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
    for vname, kw, defines in VARIANTS:
        os.environ["RAYVR_PRIMARY_DEFINES"] = defines
        with Renderer(scene, gl=gl) as r:
            for pi, ps in enumerate(poses):
                for cname, cam, n in CAMS:
                    rig = StereoRig.for_scene(scene, size=size, camera=cam)
                    rig.pose = ps
                    r.settings = RenderSettings(primary="rays", msaa=n, **kw)
                    r.warm_up(rig, seconds=0.3, min_frames=3)
                    ms = {}
                    for _ in range(5):
                        fc = r.record(rig, "both", "color", profile=True)
                        for k, v in r.read_ms(fc).items():
                            ms.setdefault(k, []).append(v)
                    st = {k: float(np.median(v)) for k, v in ms.items() if k.startswith("primary_rays")}
                    rows.append(dict(scene=name, pose=pi, msaa=n, variant=vname, stages=st))
                    print(f"{time.time()-t0:6.1f}s {name} p{pi} {n}x {vname}:", {k.split('.')[1]: round(v, 3) for k, v in st.items()}, flush=True)
                    json.dump({"device": device_meta(gl.info()), "size": size, "rows": rows}, open(out, "w"), indent=1)
# the H200-only mismatch of per-ray entries traversal (distorted chromatic 1x, Sponza's bench view)
os.environ["RAYVR_PRIMARY_DEFINES"] = ""
scene, pose = load_bench_scene("sponza")
with Renderer(scene, gl=gl) as r:
    rig = StereoRig.for_scene(scene, size=size, camera=Distorted()); rig.pose = pose
    res = {}
    for vname, kw in (("root", dict(tile_culling=False)), ("entries", dict(tile_culling=True, tile_lists=0)),
                      ("entries2", dict(tile_culling=True, tile_lists=0)), ("lists", dict(tile_culling=True, tile_lists=256))):
        r.settings = RenderSettings(primary="rays", **kw)
        f = r.render(rig, aux=("triangle",))
        res[vname] = np.stack([f.left.aux["triangle"], f.right.aux["triangle"]])
        res[vname + "_depth"] = np.stack([f.left.depth, f.right.depth])
    for k in ("entries", "entries2", "lists"):
        d = np.argwhere(res[k] != res["root"])
        print(k, "differs at", len(d), d[:12].tolist(), [(int(res["root"][tuple(i)]), int(res[k][tuple(i)]), float(res["root_depth"][tuple(i)]), float(res[k + "_depth"][tuple(i)])) for i in d[:6]], flush=True)
    d = np.argwhere(res["entries"] != res["root"])
    np.savez_compressed(os.path.join(os.path.dirname(out), "mismatch.npz"), where=d,
                        **{k: v[tuple(d.T)] for k, v in res.items()})
