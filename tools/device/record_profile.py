"""Where the CPU's recording of a frame goes on the device: cProfile over frames recorded back to back
(as bench/rays.py time_pipelined records them), the room's default_room.toml at 2x1440x1600.
Usage: python3 tools/device/record_profile.py CAMERA MSAA [FRAMES]   (CAMERA: pinhole or chromatic)"""
import cProfile, pathlib, pstats, sys, time
import numpy as np
import rayvr
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import load_config
from rayvr.frame.cameras import Distorted, Pinhole
from rayvr.frame.cameras.rig import StereoRig

camera = {"chromatic": Distorted(), "pinhole": Pinhole()}[sys.argv[1]]
msaa, frames = int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 20
with Renderer(None) as r:
    r.set_materials(load_config(pathlib.Path(rayvr.__file__).parent / "assets/default_room.toml"))
    r.settings = RenderSettings(primary="rays", msaa=msaa)
    rig = StereoRig.for_scene(r.scene, size=(1440, 1600), camera=camera)
    start = time.perf_counter()
    while time.perf_counter() - start < 2.0:  # the clocks up
        r.record(rig, "both", "color"); r.gl.ctx.finish()
    for profile in (False, True):
        profiler = cProfile.Profile()
        r.gl.ctx.finish()
        spent, t0 = [], time.perf_counter()
        for _ in range(frames):
            t1 = time.perf_counter()
            if profile:
                profiler.enable()
            r.record(rig, "both", "color")
            if profile:
                profiler.disable()
            spent.append(time.perf_counter() - t1)
        r.gl.ctx.finish()
        wall = time.perf_counter() - t0
        print(f"{sys.argv[1]} {msaa}x profiled={profile}: record median {np.median(spent) * 1e3:.2f} ms, "
              f"pipelined {wall / frames * 1e3:.2f} ms a frame")
    pstats.Stats(profiler).sort_stats("tottime").print_stats(14)
