import numpy as np, time
from rayvr.bench.scenes import bench_scenes
from rayvr.quality import metrics
from rayvr.bench import photon
from rayvr.renderer import Renderer
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
gl = create_context()
for n, scene, view in bench_scenes(("sponza",), (96, 96), {}):
    cfg = photon.config(n, 512*512, 0.05, "grid")
    rig = StereoRig(view.pose, ipd=view.ipd, fov_y=view.fov_y, near=view.near, size=(96, 96))
    with Renderer(scene, cfg, gl=gl) as r:
        imgs = {}
        for seed in (0, 1, 2, 3):
            r.settings.seed = seed
            t = time.time()
            imgs[seed] = r.render(rig, aux=("hdr",)).right.aux["hdr"].astype(np.float64)
            print(seed, round(time.time()-t, 1), "s, mean hdr", imgs[seed].mean(), flush=True)
        for s in (1, 2, 3):
            d = np.abs(imgs[s] - imgs[0]).max(-1)
            print("seed", s, "vs 0: pixels differing > 1e-3:", float((d > 1e-3).mean()), "max", float(d.max()))
