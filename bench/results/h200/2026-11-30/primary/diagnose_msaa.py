"""Diagnostic (not part of rayvr): the MSAA trace kernel, old (one invocation per pixel, looping over
its sub-rays) vs new (one invocation per sub-ray, shared-memory merge), each with msaa_count read back
directly by the CPU (the old way) or through GPU copies (the new way). Room view, 2x1440x1600."""
import sys, time
import numpy as np
import moderngl
from rayvr.gl import shaders
from rayvr.frame.passes import primary_rays as pr
from rayvr.frame.passes.compute import dispatch_per_pixel
from rayvr.bench.primary import primary_kernel_ms
from rayvr.bench.rays import time_frame
from rayvr.bench.scenes import bench_scenes
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer, RenderSettings

VARIANT = {"kernel": "new", "count": "copy"}
orig_setup, orig_dispatch, orig_execute = pr.PrimaryRaysPass.setup, pr.PrimaryRaysPass.dispatch_trace, pr.PrimaryRaysPass.execute

def setup(self, gl, plan):
    orig_setup(self, gl, plan)
    if self.msaa and VARIANT["kernel"] == "old":
        self.programs[1].release()
        from rayvr.accel.gpu import DEFAULT_BINDING, layout_defines
        d = {**layout_defines(DEFAULT_BINDING, self.layout), **pr.camera_defines(plan), "SAMPLED": int(plan.sampled),
             "MSAA_SLOTS": pr.msaa_slots(plan), "PRIMARY_MODE": 1}
        self.programs[1] = shaders.compute(gl.ctx, "rt/primary_old.comp", d)

def dispatch(self, fc):
    if VARIANT["kernel"] == "old":
        dispatch_per_pixel(fc, self.programs[1])
    else:
        orig_dispatch(self, fc)

def execute(self, fc):
    if VARIANT["count"] == "copy" or not self.msaa:
        return orig_execute(self, fc)
    # the old readback: the CPU writes and reads msaa_count itself
    rnd = fc.round
    for program in self.programs.values():
        pr.set_eye_uniforms(program, fc)
    fc.accel.layout(self.layout).bind(pr.DEFAULT_BINDING)
    gb = fc.gbuffer
    for name in ("position", "triangle"):
        gb.textures[name].bind_to_image(pr.channel(name).image, read=False, write=True)
    if "sample_weight" in fc.resources:
        fc.resource("sample_weight").bind_to_image(pr.IMAGE["sample_weight"], read=False, write=True)
    fc.resource("msaa_hits").bind_to_storage_buffer(pr.SSBO["msaa_hits"])
    count = fc.resource("msaa_count")
    count.bind_to_storage_buffer(pr.SSBO["msaa_count"])
    if rnd.first:
        count.write(np.zeros(1, np.uint32).tobytes())
        fc.stage("trace", lambda: self.dispatch_trace(fc))
        rnd.start(max(1, int(np.frombuffer(count.read(), np.uint32)[0])) if rnd.active else 1)
    self.programs[2]["msaa_slot"].value = rnd.slot
    fc.stage("select", lambda: dispatch_per_pixel(fc, self.programs[2]))

pr.PrimaryRaysPass.setup, pr.PrimaryRaysPass.dispatch_trace, pr.PrimaryRaysPass.execute = setup, dispatch, execute

gl = create_context()
scenes = sys.argv[1].split(",") if len(sys.argv) > 1 else ["default"]
SIZE = tuple(int(v) for v in (sys.argv[2] if len(sys.argv) > 2 else "1440x1600").split("x"))
for name, scene, view in bench_scenes(scenes, SIZE, {}):
    rig = StereoRig(view.pose, ipd=view.ipd, fov_y=view.fov_y, near=view.near, size=SIZE)
    for kernel, count in (("old", "direct"), ("old", "copy"), ("new", "direct"), ("new", "copy")):
        for n in (4, 16):
            VARIANT.update(kernel=kernel, count=count)
            t0 = time.perf_counter()
            with Renderer(scene, gl=gl, settings=RenderSettings(primary="rays", msaa=n)) as r:
                names, med, total = time_frame(r, rig, 8, 2)
                k, rounds = primary_kernel_ms(r, rig)
            print(f"{name} kernel={kernel:3s} count={count:6s} {n:2d}x trace {k:8.3f} ms pass "
                  f"{med.get('primary_rays', 0) - 0:8.3f} (primary_rays pass, all rounds) frame {total:8.3f} ms rounds {rounds} "
                  f"[{time.perf_counter() - t0:.1f} s]", flush=True)
gl.release()
