# Are the per-round spikes GPU bubbles (the GPU out of commands inside a pass's timer window)?
# Per-round pass ms and frame throughput, without and with a glFlush after each pass's timer end
# (run with a "glFlush": (None, ()) entry added to rayvr/gl/context.py _RAW_SIGNATURES; not kept).
import sys, time, json, numpy as np
from rayvr.bench.scenes import load_bench_scene
from rayvr.bench.head_poses import draw_poses
from rayvr.bench.vr import CAMERA_CONFIGS
from rayvr.bench import vr
from rayvr.frame.cameras.rig import StereoRig
from rayvr.frame import graph as graph_mod
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import MaterialConfig

SIZE = tuple(map(int, sys.argv[2].split("x"))) if len(sys.argv) > 2 else (1440, 1600)
orig_run = graph_mod.PassTimer.run
def flushing_run(self, name, fn):
    orig_run(self, name, fn)
    self.raw.glFlush()
out = {}
for scene_name, camera, msaa in [("default", "foveated", 4), ("sponza", "pinhole", 4), ("sponza", "distorted_chromatic", 1), ("default", "pinhole", 16)]:
    scene, _ = load_bench_scene(scene_name)
    model, fov, primary = CAMERA_CONFIGS[camera]
    heads = draw_poses(scene, scene_name, 3, 22)
    with Renderer(scene) as r:
        r.set_materials(MaterialConfig(default="shadows"))
        r.settings = RenderSettings(primary=primary, msaa=msaa)
        for head in heads:
            rig = StereoRig(head.pose, fov_y=fov or 75.0, size=SIZE, camera=model)
            for mode in ("plain", "flush", "plain", "flush"):
                graph_mod.PassTimer.run = flushing_run if mode == "flush" else orig_run
                r.warm_up(rig, seconds=1.0, min_frames=5)
                sums, rounds = [], []
                for i in range(10):
                    fc = r.record(rig, "both", "color"); r.gl.ctx.finish()
                    rm = r.read_round_ms(fc)
                    sums.append(sum(sum(v) for v in rm.values())); rounds.append(rm)
                t0 = time.perf_counter()
                for i in range(20):
                    r.record(rig, "both", "color")
                r.gl.ctx.finish()
                wall = (time.perf_counter() - t0) / 20 * 1e3
                k = f"{scene_name} {camera} {msaa}x pose {head.index} {mode}"
                med = {n: [round(float(np.median([rr[n][j] for rr in rounds if n in rr and len(rr[n]) > j])), 3) for j in range(max(len(rr.get(n, [])) for rr in rounds))] for n in rounds[0]}
                out[k] = {"sum_ms_median": float(np.median(sums)), "sum_ms_max": float(max(sums)), "wall_ms_per_frame": wall, "rounds": med}
                print(f"{k:45s} sum median {np.median(sums):.2f} max {max(sums):.2f} wall/frame {wall:.2f}", flush=True)
                print("   ", {n: v for n, v in med.items() if max(v) > 0.2}, flush=True)
json.dump(out, open(sys.argv[1], "w"), indent=1)
