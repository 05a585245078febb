import numpy as np
from PIL import Image
from rayvr.renderer import Renderer, RenderSettings
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.rig import StereoRig
from rayvr.scene.materials import load_config
from rayvr.bench.rays import hybrid_config
with Renderer(None, load_config("rayvr/assets/default_room.toml")) as r:
    rig = StereoRig.for_scene(r.scene, size=(320, 356), camera=Distorted())
    out = []
    for share, msaa in ((False, 1), (True, 1), (True, 4)):
        r.settings = RenderSettings(primary="rays", share_channel_shading=share, msaa=msaa, seed=1)
        f = r.render(rig, spp=4)
        out.append(f.left.color.astype(int))
    diff = np.clip(np.abs(out[0] - out[1]) * 4, 0, 255)
    Image.fromarray(np.concatenate(out + [diff], 1).astype(np.uint8)).save("/tmp/w/shared_pic.png")
