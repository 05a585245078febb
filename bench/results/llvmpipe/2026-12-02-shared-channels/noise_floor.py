"""The room's noise floor for flip.json: FLIP between two frames that both shade every channel,
with different seeds (the sampled effects' noise alone), at measure.py's size, spp and ppd.
Run from the repository root: python bench/results/llvmpipe/2026-12-02-shared-channels/noise_floor.py OUT_DIR"""
import json
import sys

from rayvr.bench.rays import hybrid_config
from rayvr.bench.report import device_meta
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.quality.metrics import DEFAULT_PPD, flip
from rayvr.renderer import Renderer, RenderSettings

SIZE, SPP = (480, 534), 32
PPD = DEFAULT_PPD * SIZE[0] / 1440
gl = create_context()
with Renderer(None, hybrid_config("default"), gl=gl) as r:
    rig = StereoRig.for_scene(r.scene, size=SIZE, camera=Distorted())
    images = []
    for seed in (1, 2):
        r.settings = RenderSettings(primary="rays", share_channel_shading=False, seed=seed)
        images.append(r.render(rig, spp=SPP).left.color / 255.0)
row = {"scene": "default", "config": "shadows", "spp": SPP, "ppd": PPD, "seeds": [1, 2],
       "flip_left_apart_vs_apart": flip(images[0], images[1], ppd=PPD, float_encoding="srgb")}
print(row)
json.dump({"meta": {**device_meta(gl.info()), "what": __doc__}, "rows": [row]},
          open(f"{sys.argv[1]}/noise_floor.json", "w"), indent=1)
