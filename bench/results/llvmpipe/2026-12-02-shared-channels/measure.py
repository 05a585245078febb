"""FLIP of shared channel shading against shading every channel (distorted chromatic camera, 1x),
on the bench scenes' views at a third of the headset's resolution; the share of red and blue pixels
that took green's shading. Image error does not depend on the device (llvmpipe here). Both images
are the mean of SPP samples: the sampled effects' noise (soft shadows, glossy) differs between
the two by construction (shared channels take green's sample), so single frames would measure noise.
The reference (every channel shaded) and the variant (shared) use different seeds (1, 2); noise_floor.py
gives FLIP between two references of those seeds: what noise alone costs.
Run from the repository root: python bench/results/llvmpipe/2026-12-02-shared-channels/measure.py OUT_DIR"""
import json
import sys
import time

import numpy as np

from rayvr.bench.rays import hybrid_config
from rayvr.bench.report import device_meta
from rayvr.bench.scenes import bench_scenes, shipped_config
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.quality.metrics import DEFAULT_PPD, flip
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import load_config

SIZE = (480, 534)  # per eye: a third of 1440x1600
SPP = {"default": 32, "sponza": 8}
PPD = DEFAULT_PPD * SIZE[0] / 1440  # the headset's pixels per degree, at this width
gl = create_context()
rows, skipped = [], {}
for name, scene, rig in bench_scenes(("default", "sponza"), SIZE, skipped):
    configs = {"shadows": hybrid_config(name)}
    if name == "default":
        configs["room"] = load_config(shipped_config(name))
    cam_rig = StereoRig.for_scene(scene, size=SIZE, camera=Distorted())
    cam_rig.pose = rig.pose
    for cname, config in configs.items():
        with Renderer(scene, config, gl=gl) as r:
            images, match = {}, None
            for share in (False, True):
                r.settings = RenderSettings(primary="rays", share_channel_shading=share, seed=2 if share else 1)
                t = time.time()
                f = r.render(cam_rig, spp=SPP[name])
                images[share] = np.stack([f.left.color, f.right.color]) / 255.0
                if share:
                    w, h = SIZE
                    match = np.frombuffer(r.resource("channel_match").read(), np.uint32).reshape(2, h, w)
            row = {"scene": name, "config": cname, "per_eye_size": list(SIZE), "ppd": PPD, "spp": SPP[name],
                   "flip_left": flip(images[False][0], images[True][0], ppd=PPD, float_encoding="srgb"),
                   "flip_right": flip(images[False][1], images[True][1], ppd=PPD, float_encoding="srgb"),
                   "red_shared": float((match & 1 != 0).mean()), "blue_shared": float((match & 4 != 0).mean()),
                   "max_8bit_difference": int(np.abs(images[False] - images[True]).max() * 255 + 0.5)}
            rows.append(row)
            print(row, flush=True)
json.dump({"meta": {**device_meta(gl.info()), "what": __doc__, "skipped": skipped}, "rows": rows},
          open(f"{sys.argv[1]}/flip.json", "w"), indent=1)
