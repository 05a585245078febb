"""Traversal work per ray of the bench views' central camera rays (the rays `bench primary` traces
standalone): per ray from the root, from tile entry lists in tree order, and front to back along the
tile's central direction (the default). Counted on the GPU (bvh.glsl BVH_COUNT_WORK): the counts
depend on the BVH and the rays, not on the device, so llvmpipe gives the H200's.

    PYTHONPATH=. python bench/results/llvmpipe/tile_order/tile_work.py 720x800
"""
import json
import sys

from rayvr.accel.scene import build_scene_bvh
from rayvr.accel.gpu import GpuBvh
from rayvr.bench.primary import tile_work
from rayvr.bench.rays import primary_rays
from rayvr.bench.scenes import bench_scenes
from rayvr.gl.context import create_context

size = tuple(int(x) for x in (sys.argv[1] if len(sys.argv) > 1 else "720x800").split("x"))
gl = create_context()
skipped, rows = {}, []
for name, scene, rig in bench_scenes(("default", "sponza"), size, skipped):
    o, d = primary_rays(rig, scene.origin, tiled=True)
    work = tile_work(gl, GpuBvh(gl.ctx, build_scene_bvh(scene, progress=False)), o, d)
    rows.append({"scene": name, "size": f"2x{size[0]}x{size[1]}", "rays": len(o), **work})
    print(json.dumps(rows[-1]), flush=True)
print("skipped", skipped)
