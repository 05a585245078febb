"""Where the denoiser's time goes on this device: the room with default_room.toml at 2x1440x1600,
the bench pose and 3 random head poses (bench vr's), per denoise stage, 4 iterations, median of 9 frames."""
import json, sys
import numpy as np
from dataclasses import replace
from rayvr.bench.scenes import bench_scenes, shipped_config
from rayvr.bench.head_poses import draw_poses
from rayvr.bench.report import device_meta
from rayvr.scene.materials import load_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.gl.context import create_context

out = sys.argv[1]
gl = create_context()
rows = []
for name, scene, rig in bench_scenes(["default"], (1440, 1600), {}):
    poses = [rig.pose] + [h.pose for h in draw_poses(scene, name, 3, 22)]
    with Renderer(scene, load_config(shipped_config(name)), gl=gl) as r:
        for pi, pose in enumerate(poses):
            rig.pose = pose
            for denoise in (False, True):
                r.settings = RenderSettings(denoise=denoise, denoise_iterations=4)
                r.warm_up(rig, seconds=1.0, min_frames=5)
                ms = {}
                for _ in range(9):
                    fc = r.record(rig, "both", "color", profile=True)
                    for k, v in r.read_ms(fc).items():
                        ms.setdefault(k, []).append(v)
                med = {k: float(np.median(v)) for k, v in ms.items()}
                med["frame"] = sum(v for k, v in med.items() if "." not in k)
                rows.append(dict(pose=pi, denoise=denoise, ms=med))
                print(pi, denoise, {k: round(v, 3) for k, v in med.items() if k.startswith("denoise") or k == "frame"}, flush=True)
json.dump({"device": device_meta(gl.info()), "size": [1440, 1600], "rows": rows}, open(out, "w"), indent=1)
