"""Probe (tools/device/README.md): what --shading-slots N changes in the headset frame's image against
every distinct triangle shaded (8 slots), on bench vr's head poses of the room (default_room.toml)
and Sponza (hybrid), distorted chromatic camera at 4x MSAA.
`python3 tools/device/probe_slots.py W H POSES SLOTS...` prints, per scene, pose and N: mean FLIP of
N's frame against 8's (both eyes, LDR), the share of pixels that differ, and the largest difference."""
import sys

import numpy as np

from rayvr.bench import vr
from rayvr.bench.vr import CAMERA_CONFIGS, bench_scenes, draw_poses, materials_config
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.quality.metrics import flip
from rayvr.renderer import Renderer, RenderSettings

size = (int(sys.argv[1]), int(sys.argv[2]))
poses, slots = int(sys.argv[3]), [int(x) for x in sys.argv[4:]] or [4, 3]
gl = create_context(None)
print(gl.info()["renderer"], flush=True)
model, fov, primary = CAMERA_CONFIGS["distorted_chromatic"]
for scene_name, config in (("default", "room"), ("sponza", "shadows")):
    try:
        (name, scene, view), = list(bench_scenes([scene_name], size, {}))
    except ValueError as e:
        print(scene_name, "skipped:", e)
        continue
    heads = draw_poses(scene, name, poses, vr.POSE_SEED)
    mats, _ = materials_config(gl, config, name, scene, view, 11.1, False)
    with Renderer(scene, gl=gl) as r:
        r.set_materials(mats)
        for head in heads:
            rig = StereoRig(head.pose, ipd=view.ipd, fov_y=fov or view.fov_y, near=view.near, size=size, camera=model)
            images = {}
            for n in [8, *slots]:
                r.settings = RenderSettings(primary=primary, msaa=4, shading_slots=n)
                f = r.render(rig)
                images[n] = np.concatenate([np.asarray(f.left.color), np.asarray(f.right.color)], 1)[..., :3]
            for n in slots:
                a, b = images[8].astype(np.float32) / 255, images[n].astype(np.float32) / 255
                d = np.abs(a - b).max(-1)
                print(f"{name} pose {head.index} ({head.kind}) slots {n}: FLIP vs 8 {flip(a, b, float_encoding='srgb'):.5f}, "
                      f"pixels changed {(d > 0).mean() * 100:.2f} %, largest {d.max() * 255:.0f}/255", flush=True)
