"""Probe 2 (tools/device/README.md): which change brings back the pixel events' shadow counts of a renderer's second counting frame on the H100 (Sponza hybrid, 320x180): `python3 tools/device/probe_counts2.py`."""
import sys
import numpy as np
from rayvr.bench import vr
from rayvr.bench.vr import bench_scenes, draw_poses, materials_config, StereoRig, Renderer, RenderSettings
from rayvr.gl.context import create_context
import rayvr.frame.passes.trace_effect as T
import rayvr.frame.passes.compute as C

size = (320, 180)
gl = create_context(None)
(name, scene, view), = list(bench_scenes(["sponza"], size, {}))
heads = draw_poses(scene, name, 2, vr.POSE_SEED)
mats, _ = materials_config(gl, "shadows", name, scene, view, 11.1, False)
rig = StereoRig(heads[1].pose, ipd=view.ipd, fov_y=view.fov_y, near=view.near, size=size)

def fresh():
    r = Renderer(scene, gl=gl)
    r.set_materials(mats)
    r.settings = RenderSettings(primary="rays", msaa=1)
    return r

def counts(r):
    return {k: (v["closest"], v["shadow"]) for k, v in T.count_rays(r, rig).items()}

def manual(r, frames):
    """count_rays' steps with count_rays left on over `frames` frames, then read."""
    passes = [p for p in r.compiled(r.plan(camera=rig.camera)).passes if isinstance(p, T.TraceEffectPass)]
    r.render(rig)
    for p in passes:
        p.count_rays = True
        r.resource(p.buffers["args"][0]).write(np.zeros(4, np.uint32).tobytes(), offset=T.COUNTERS_OFFSET)
    for _ in range(frames):
        r.render(rig)
    out = {p.effect.name: np.frombuffer(r.resource(p.buffers["args"][0]).read(), np.uint32)[8:10].tolist() for p in passes}
    for p in passes:
        p.count_rays = False
    return out

r = fresh(); print("X0 first", counts(r)); print("X0 second", counts(r)); print("X0 third", counts(r), flush=True)
r = fresh(); print("X3 manual 1", manual(r, 1)); print("X3 manual 1 again", manual(r, 1)); print("X3 manual 3", manual(r, 3), flush=True)
real = C.write_uniforms
def nocache(program, fc, values):
    for n, v in values.items():
        if C.declares(program, n):
            if isinstance(v, bytes):
                program[n].write(v)
            else:
                program[n].value = v
T.write_uniforms = nocache
r = fresh(); print("X1 nocache first", counts(r)); print("X1 nocache second", counts(r), flush=True)
T.write_uniforms = real
# X2: fresh programs for the pass before the second count
r = fresh(); print("X2 first", counts(r))
for p in r.compiled(r.plan(camera=rig.camera)).passes:
    if isinstance(p, T.TraceEffectPass):
        p.programs.pop("shadow_every", None); p.programs.pop("shadow_finish_every", None)
print("X2 rebuilt plain kernels, second", counts(r), flush=True)
# X4: a frame with every uniform left as is but the args buffer re-zeroed wholly
r = fresh(); print("X4 first", counts(r))
for p in r.compiled(r.plan(camera=rig.camera)).passes:
    if isinstance(p, T.TraceEffectPass):
        r.resource(p.buffers["args"][0]).write(np.zeros(12, np.uint32).tobytes())
print("X4 args zeroed wholly, second", counts(r), flush=True)
