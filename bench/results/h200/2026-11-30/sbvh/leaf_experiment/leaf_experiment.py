"""Device experiment: BVH leaf size / SAH triangle cost vs GRays/s per ray kind (bvh2, bvh4)."""
import json, sys, time
import numpy as np
from rayvr.accel.bvh import build_bvh
from rayvr.accel.gpu import GpuBvh, RayTracer
from rayvr.bench.rays import primary_rays, secondary_rays
from rayvr.bench.scenes import bench_scenes
from rayvr.gl.context import create_context

out = sys.argv[1]
size = tuple(int(x) for x in sys.argv[2].split("x")) if len(sys.argv) > 2 else (1440, 1600)
scenes = tuple(sys.argv[3].split(",")) if len(sys.argv) > 3 else ("sponza", "default")
gl = create_context()
rows = []
for name, scene, rig in bench_scenes(scenes, size, {}):
    V, I = scene.vertices, scene.indices
    ref = build_bvh(V, I)
    rt = RayTracer(gl, GpuBvh(gl, ref, layout="bvh2"))
    o, d = primary_rays(rig, scene.origin, tiled=True)
    hits = rt.trace(o, d)
    rays = {"primary": (o, d, np.float32(3e38), "closest"), **secondary_rays(scene, ref, o, d, hits)}
    builds = [("sah", 8, 1.0), ("sah", 4, 1.0), ("sah", 2, 1.0), ("sah", 8, 2.0), ("sah", 4, 0.5)]
    if name == "sponza":
        builds += [("sbvh", 8, 1.0), ("sbvh", 4, 1.0)]
    for build, leaf, tcost in builds:
        t0 = time.perf_counter()
        bvh = build_bvh(V, I, max_leaf_size=leaf, triangle_cost=tcost, spatial_splits=build == "sbvh")
        bs = time.perf_counter() - t0
        for layout in ("bvh2", "bvh4"):
            g = GpuBvh(gl, bvh, layout=layout)
            vrt = RayTracer(gl, g)
            for kind, (ro, rd, tmax, mode) in rays.items():
                t = vrt.time_trace(ro, rd, tmax=tmax, mode=mode, repeats=20)
                row = dict(scene=name, build=build, max_leaf=leaf, triangle_cost=tcost, build_s=bs,
                           sah_cost=bvh.sah_cost(), layout=layout, kind=kind, rays=len(ro),
                           gpu_ms=t["gpu_ms"], grays_s=t["rays_per_s"] / 1e9)
                rows.append(row)
                print(json.dumps(row), flush=True)
                json.dump({"device": gl.info(), "rows": rows}, open(out, "w"), indent=1, default=str)
