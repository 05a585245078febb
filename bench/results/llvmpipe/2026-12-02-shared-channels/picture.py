"""sponza_apart_shared_diff.png: Sponza's bench view, distorted chromatic camera, left eye at 360x400: every channel shaded apart | shared channel shading | their difference x4. Run from the repository root."""
import numpy as np
from PIL import Image
from rayvr.bench.rays import hybrid_config
from rayvr.bench.scenes import load_bench_scene
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer, RenderSettings
gl = create_context()
scene, pose = load_bench_scene("sponza")
with Renderer(scene, hybrid_config("sponza"), gl=gl) as r:
    rig = StereoRig.for_scene(scene, size=(360, 400), camera=Distorted()); rig.pose = pose
    im = {}
    for share in (False, True):
        r.settings = RenderSettings(primary="rays", share_channel_shading=share)
        im[share] = r.render(rig).left.color.astype(int)  # seed 0 both: Sponza has no sampled effect
    d = np.abs(im[True] - im[False]).max(-1)
    print("max", d.max(), "p99.9", np.percentile(d, 99.9), "p99", np.percentile(d, 99), "share>8", (d > 8).mean())
    Image.fromarray(np.concatenate([im[False], im[True], np.repeat(np.minimum(d * 4, 255)[..., None], 3, -1)], 1).astype(np.uint8)).save("bench/results/llvmpipe/2026-12-02-shared-channels/sponza_apart_shared_diff.png")
