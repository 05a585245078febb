"""FLIP of shared channel shading (the three colour channel sets cast together as sub-rays, a pixel
shaded once per distinct triangle: frame/passes/primary_rays.py shares_channels) against shading
every channel set on its own, distorted chromatic camera at 1x and 4x MSAA, on the bench scenes'
views at a third of the headset's resolution; the share of pixels whose channel sets' rays all hit
one triangle (one shading round). Image error does not depend on the device (llvmpipe here). Both
images are the mean of SPP samples (the sampled effects' noise differs between the two by
construction); the reference (every set shaded) and the variant (shared) use different seeds (1, 2).
Run from the repository root: python bench/results/llvmpipe/2026-12-03-shared-channel-samples/measure.py OUT_DIR"""
import json
import sys

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
        for msaa in (1, 4):
            with Renderer(scene, config, gl=gl) as r:
                images, one = {}, None
                for share in (False, True):
                    r.settings = RenderSettings(primary="rays", msaa=msaa, share_channel_shading=share,
                                                seed=2 if share else 1)
                    f = r.render(cam_rig, spp=SPP[name])
                    images[share] = np.stack([f.left.color, f.right.color]) / 255.0
                    if share:
                        w, h = SIZE
                        hits = np.frombuffer(r.resource("msaa_hits").read(), np.uint32)[:2 * w * h * 4].reshape(-1, 4)
                        one = float((((hits[:, 2] >> 8) & 255) == 1).mean())
                row = {"scene": name, "config": cname, "msaa": msaa, "per_eye_size": list(SIZE), "ppd": PPD,
                       "spp": SPP[name],
                       "flip_left": flip(images[False][0], images[True][0], ppd=PPD, float_encoding="srgb"),
                       "flip_right": flip(images[False][1], images[True][1], ppd=PPD, float_encoding="srgb"),
                       "one_triangle_pixels": one,
                       "max_8bit_difference": int(np.abs(images[False] - images[True]).max() * 255 + 0.5)}
                rows.append(row)
                print(row, flush=True)
json.dump({"meta": {**device_meta(gl.info()), "what": __doc__, "skipped": skipped}, "rows": rows},
          open(f"{sys.argv[1]}/flip.json", "w"), indent=1)
