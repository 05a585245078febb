"""Where do tile-culled and per-ray traversal disagree on Sponza (bench view, both eyes)? llvmpipe."""
import sys, time, numpy as np
from rayvr.bench.scenes import bench_scenes
from rayvr.bench.rays import primary_rays
from rayvr.accel.gpu import RayTracer, GpuBvh
from rayvr.accel.scene import build_scene_bvh
from rayvr.accel.bvh import trace_brute_force
from rayvr.gl.context import create_context
gl = create_context(None)
w, h = (int(x) for x in sys.argv[1].split("x"))
for name, scene, rig in bench_scenes(("sponza",), (w, h), {}):
    bvh = build_scene_bvh(scene)
    g = GpuBvh(gl.ctx, bvh)
    o, d = primary_rays(rig, scene.origin, tiled=True)
    rt = RayTracer(gl.ctx, g)
    t0 = time.time(); a = rt.trace(o, d); b = rt.trace(o, d, tiles=True); print("traced", len(o), time.time() - t0)
    bad = np.flatnonzero(a.prim != b.prim)
    print("disagree", len(bad), "of", len(o))
    for i in bad[:10]:
        ref = trace_brute_force(scene.vertices, scene.indices, o[i:i+1], d[i:i+1])
        print(i, "plain", a.prim[i], a.t[i], "tiles", b.prim[i], b.t[i], "brute", ref.prim[0] if hasattr(ref, 'prim') else ref)
