"""Probe (tools/device/README.md): what the MSAA merge by smooth surface (--shading-merge surface) and
fewer shading slots save in the headset frame, and what they cost in image error.
`python3 tools/device/probe_merge.py W H POSES [REF_SPP [FRAMES]]` prints, for the room (default_room.toml)
and Sponza (hybrid) through the distorted chromatic camera at 4x MSAA, on bench vr's head poses: per
variant (merge by triangle with 8 slots, the default, and with 4 and 3; by surface with 8, 4 and 2 slots) the
rounds, the GPU timer sum (median of FRAMES, default 8, after warm-up; 0: not timed, for a CPU) and mean FLIP of both eyes against a
converged frame: every sub-ray shaded with the colour channels apart (--ssaa, no shared channel
shading: the frame MSAA approximates), REF_SPP samples (default 64), its own seed. Each pose first
prints what the frame shows (bench vr's effect share: the share of its pixels per effect); REF_SPP 0
prints only that."""
import sys

import numpy as np

from rayvr.bench import vr
from rayvr.bench.report import share_text
from rayvr.bench.vr import CAMERA_CONFIGS, bench_scenes, draw_poses, frame_share, materials_config
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.quality.metrics import flip
from rayvr.renderer import Renderer, RenderSettings

size = (int(sys.argv[1]), int(sys.argv[2]))
poses = int(sys.argv[3])
ref_spp = int(sys.argv[4]) if len(sys.argv) > 4 else 64
frames = int(sys.argv[5]) if len(sys.argv) > 5 else 8
VARIANTS = (("triangle", 8), ("triangle", 4), ("triangle", 3), ("surface", 8), ("surface", 4), ("surface", 2))
gl = create_context(None)
print(gl.info()["renderer"], flush=True)
model, fov, primary = CAMERA_CONFIGS["distorted_chromatic"]


def both(frame):
    return np.concatenate([np.asarray(frame.left.color), np.asarray(frame.right.color)], 1)[..., :3].astype(np.float32) / 255


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
            r.settings = RenderSettings(primary=primary, msaa=4)
            print(f"{name} pose {head.index} ({head.kind}) shows {share_text(frame_share(r, rig, mats))}", flush=True)
            if not ref_spp:
                continue
            r.settings = RenderSettings(primary=primary, msaa=4, ssaa=True, share_channel_shading=False, seed=1000)
            reference = both(r.render(rig, spp=ref_spp))
            for merge, slots in VARIANTS:
                r.settings = RenderSettings(primary=primary, msaa=4, shading_merge=merge, shading_slots=slots)
                if frames:
                    r.warm_up(rig, seconds=1.0, min_frames=3)
                gpu, rounds = [], 0
                for _ in range(max(frames, 1)):
                    fc = r.record(rig, "both", "color")
                    gpu.append(sum(r.read_ms(fc).values()))
                    rounds = len(r.read_round_ms(fc).get("sample_accumulate", [])) or 1
                image = both(r.render(rig))
                print(f"{name} pose {head.index} ({head.kind}) {merge} slots {slots}: rounds {rounds}, "
                      f"GPU {np.median(gpu):.2f} ms, FLIP vs converged {flip(reference, image, float_encoding='srgb'):.5f}",
                      flush=True)
