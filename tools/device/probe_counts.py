"""Probe (tools/device/README.md): the ray counters and images of Sponza's hybrid frame over poses, renderers and bench vr's steps: `python3 tools/device/probe_counts.py W H` (PROBE_OUT=DIR: PNGs)."""
import sys, json
import numpy as np
from rayvr.bench import vr
from rayvr.bench.vr import bench_scenes, draw_poses, materials_config, StereoRig, Renderer, RenderSettings, count_rays, time_frame, time_pipelined
from rayvr.gl.context import create_context
from rayvr.frame.passes.trace_effect import TraceEffectPass

size = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (640, 360)
gl = create_context(None)
print(gl.info())
(name, scene, view), = list(bench_scenes(["sponza"], size, {}))
heads = draw_poses(scene, name, 4, vr.POSE_SEED)
mats, _ = materials_config(gl, "shadows", name, scene, view, 11.1, False)

def rigs():
    return [StereoRig(h.pose, ipd=view.ipd, fov_y=view.fov_y, near=view.near, size=size) for h in heads]

def show(tag, r, rig):
    c = count_rays(r, rig)
    args = {p.effect.name: np.frombuffer(r.resource(p.buffers["args"][0]).read(), np.uint32).tolist()
            for p in r.compiled(r.plan(camera=rig.camera)).passes if isinstance(p, TraceEffectPass)}
    f = r.render(rig)
    import os
    if os.environ.get("PROBE_OUT"):
        from PIL import Image
        c8 = np.asarray(f.left.color)
        c8 = c8 if c8.dtype == np.uint8 else np.clip(c8 * 255, 0, 255).astype(np.uint8)
        Image.fromarray(c8[..., :3]).save(f"{os.environ['PROBE_OUT']}/{tag.replace(' ', '_')}_{size[0]}.png")
    print(tag, {k: (v["closest"], v["shadow"], v["pixels"]) for k, v in c.items()}, "args", args,
          "mean", float(np.asarray(f.left.color, np.float32).mean()), flush=True)
    return f

def fresh():
    r = Renderer(scene, gl=gl)
    r.set_materials(mats)
    r.settings = RenderSettings(primary="rays", msaa=1)
    return r

R = rigs()
print("== A: one renderer, count at each pose, no timing")
r = fresh()
for i, rig in enumerate(R):
    show(f"A pose{i}", r, rig)
show("A pose0 again", r, R[0])
show("A pose0 again2", r, R[0])
print("== B: fresh renderer, pose1 first, twice")
r2 = fresh()
show("B pose1", r2, R[1]); show("B pose1 again", r2, R[1])
print("== C: fresh renderer, pose1, after timing")
r3 = fresh()
time_frame(r3, R[1], 5, 3, 0.3); time_pipelined(r3, R[1])
show("C pose1 timed", r3, R[1])
print("== D: fresh renderer per pose")
for i, rig in enumerate(R):
    show(f"D pose{i}", fresh(), rig)

print("== E-H: bench vr itself at this size, 3 poses, with parts of frame_row left out")
import rayvr.bench.vr as V
real = {k: getattr(V, k) for k in ("frame_share", "time_pipelined", "primary_stages", "round_passes")}
def bench(tag, **skip):
    for k, f in real.items():
        setattr(V, k, f)
    for k in skip:
        setattr(V, k, {"frame_share": lambda r, rig, c: {}, "time_pipelined": lambda r, rig: {},
                       "primary_stages": lambda r, rig: {}, "round_passes": lambda r, rig: {}}[k])
    res = V.run(f"/tmp/probe_{tag}", size=size, scenes=("sponza",), poses=3, cameras=("pinhole",), counts=(1,),
                configs=("shadows",), repeat=3, warmup=2, progress=False, gl=gl)
    for row in res["rows"]:
        print(tag, row["pose"]["index"], {k: (v["closest"], v["shadow"]) for k, v in row["rays"].items()},
              round(row["frame_ms"], 3), flush=True)
bench("E_all")
bench("F_noshare", frame_share=1)
bench("G_nopipe", time_pipelined=1)
bench("H_nostages", primary_stages=1, round_passes=1)
bench("I_none", frame_share=1, time_pipelined=1, primary_stages=1, round_passes=1)
