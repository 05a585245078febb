# CPU time of recording one stereo frame (Renderer.record, the GPU finished first), 8x8 pixels an eye so
# that llvmpipe's share is small: python rec_time.py CAMERA MSAA LABEL (run with LP_NUM_THREADS=0).
import time, sys, numpy as np
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import MaterialConfig
from rayvr.frame.cameras import Foveated, Pinhole
from rayvr.frame.cameras.rig import StereoRig
cam = {"foveated": Foveated(), "pinhole": Pinhole()}[sys.argv[1]]
with Renderer(None) as r:
    r.set_materials(MaterialConfig(default="shadows"))
    r.settings = RenderSettings(primary="rays", msaa=int(sys.argv[2]))
    rig = StereoRig.for_scene(r.scene, size=(8, 8), camera=cam)
    for _ in range(10):
        r.record(rig, "both", "color"); r.gl.ctx.finish()
    t = []
    for _ in range(200):
        r.gl.ctx.finish(); t0 = time.perf_counter(); r.record(rig, "both", "color"); t.append(time.perf_counter() - t0)
    print(sys.argv[1:], "record ms median %.3f p10 %.3f" % (np.median(t) * 1e3, np.percentile(t, 10) * 1e3))
