"""How many pixels each MSAA shading round has to shade: per pixel of the left eye, the distinct
triangles its N sub-rays hit (Embree, the same sub-ray positions as the renderer's camera model),
on bench vr's head poses (seed 22) at 1440x1600. Round k shades the pixels with more than k
distinct triangles; the frame runs as many rounds as the most any pixel has.
Usage: python msaa_rounds.py SCENE N [POSES]"""
import sys

import numpy as np
from embreex import mesh_construction, rtcore_scene

from rayvr.bench.head_poses import draw_poses
from rayvr.bench.scenes import load_bench_scene
from rayvr.frame.cameras.rig import StereoRig

name, n = sys.argv[1], int(sys.argv[2])
poses = int(sys.argv[3]) if len(sys.argv) > 3 else 5
scene, _ = load_bench_scene(name)
fov = 90.0 if name == "sponza" else 75.0  # bench vr's rig (vr.md)
verts = (scene.vertices.astype(np.float64) + scene.origin).astype(np.float32)
embree = rtcore_scene.EmbreeScene()
mesh_construction.TriangleMesh(embree, verts, scene.indices.astype(np.int32))
for head in draw_poses(scene, name, poses, 22):
    eye = StereoRig(head.pose, ipd=0.064, fov_y=fov, near=0.01, size=(1440, 1600)).eye("left")
    ids = []
    for i in range(n):
        rays = eye.camera.rays(eye, 0, (i, n))
        ids.append(embree.run(np.ascontiguousarray(rays.origins.reshape(-1, 3), np.float32),
                              np.ascontiguousarray(rays.directions.reshape(-1, 3), np.float32)))
    ids = np.sort(np.stack(ids, -1), axis=-1)
    distinct = 1 + np.count_nonzero(np.diff(ids, axis=-1), axis=-1)
    share = [float((distinct > k).mean()) for k in range(int(distinct.max()))]
    print(f"{name} {n}x pose {head.index}: rounds {len(share)}, share of pixels each round shades: "
          + " ".join(f"{s:.4f}" for s in share), flush=True)
