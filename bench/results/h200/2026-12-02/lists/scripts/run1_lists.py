"""Primary visibility with and without tile triangle lists, H200, random head poses (ad hoc, before bench vr)."""
import json, os, sys, time
import numpy as np
from rayvr.bench.scenes import load_bench_scene
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Pinhole, Distorted, Foveated, Wide, ThinLens
from rayvr.renderer import Renderer, RenderSettings
from rayvr.gl.context import create_context
from rayvr.bench.report import device_meta

out = sys.argv[1]
size = tuple(int(x) for x in os.environ.get("SIZE", "1440x1600").split("x"))
gl = create_context()
rng = np.random.default_rng(int(os.environ.get("SEED", "7")))
CAMS = [("pinhole", Pinhole(), 1, None), ("pinhole", Pinhole(), 4, None), ("pinhole", Pinhole(), 16, None),
        ("pinhole", Pinhole(), 32, None), ("distorted_chromatic", Distorted(), 1, None),
        ("distorted_chromatic", Distorted(), 16, None), ("foveated", Foveated(), 1, None),
        ("wide", Wide(fov_x=210.0), 1, 130.0), ("dof", ThinLens(aperture=0.0015, focus=0.5), 4, None)]
VARIANTS = {"root": dict(tile_culling=False), "entries": dict(tile_culling=True, tile_lists=0),
            "lists256": dict(tile_culling=True, tile_lists=256), "lists1024": dict(tile_culling=True, tile_lists=1024)}
rows = []
t0 = time.time()
for name in ("sponza", "default"):
    scene, pose = load_bench_scene(name)
    lo, hi = scene.bounds
    poses = [pose] if pose is not None else []
    while len(poses) < 3:
        c = lo + (hi - lo) * np.array([0.25 + 0.5 * rng.random(), 0.0, 0.25 + 0.5 * rng.random()])
        c[1] = lo[1] + (hi[1] - lo[1]) * (0.2 + 0.3 * rng.random())
        yaw, pitch = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(-20, 20))
        d = np.array([np.cos(pitch) * np.sin(yaw), np.sin(pitch), np.cos(pitch) * np.cos(yaw)])
        poses.append(Pose.look_at(c, c + d))
    with Renderer(scene, gl=gl) as r:
        for pi, ps in enumerate(poses):
            for cname, cam, n, fov in CAMS:
                rig = StereoRig.for_scene(scene, size=size, camera=cam, **({"fov_y": fov} if fov else {}))
                rig.pose = ps
                ref = None
                for vname, kw in VARIANTS.items():
                    r.settings = RenderSettings(primary="rays", msaa=n, **kw)
                    r.warm_up(rig, seconds=0.3, min_frames=3)
                    ms = {}
                    for _ in range(5):
                        fc = r.record(rig, "both", "color", profile=True)
                        for k, v in r.read_ms(fc).items():
                            ms.setdefault(k, []).append(v)
                    med = {k: float(np.median(v)) for k, v in ms.items()}
                    prim = sum(v for k, v in med.items() if k in ("primary_rays.trace", "primary_rays.cast", "primary_rays.cull", "primary_rays.lists"))
                    frame = float(np.median(np.sum([ms[k] for k in ms], axis=0)))
                    row = dict(scene=name, pose=pi, camera=cname, msaa=n, variant=vname, primary_ms=prim, frame_ms=frame,
                               stages={k: v for k, v in med.items() if k.startswith("primary_rays")})
                    if pi == 0 and n <= 16:
                        f = r.render(rig, aux=("triangle",))
                        tri = np.stack([f.left.aux["triangle"], f.right.aux["triangle"]])
                        if ref is None:
                            ref = tri
                        else:
                            row["tri_equal_root"] = bool(np.array_equal(ref, tri))
                    if kw.get("tile_lists"):
                        w = np.frombuffer(r.resource("tile_tris").read(), np.uint32).reshape(-1, 2 * (kw["tile_lists"] + 1))[:, 0]
                        row["overflow_share"] = float((w == 0xFFFFFFFF).mean())
                        ok = w[w != 0xFFFFFFFF]
                        row["list_mean"] = float(ok.mean()) if len(ok) else 0.0
                        row["list_p99"] = float(np.percentile(ok, 99)) if len(ok) else 0.0
                    rows.append(row)
                    print(f"{time.time()-t0:6.1f}s {name} p{pi} {cname} {n}x {vname}: primary {prim:.3f} ms frame {frame:.3f}",
                          {k: round(v, 3) for k, v in row.items() if k in ("tri_equal_root", "overflow_share", "list_mean", "list_p99")}, flush=True)
                    json.dump({"device": device_meta(gl.info()), "size": size, "rows": rows}, open(out, "w"), indent=1)
