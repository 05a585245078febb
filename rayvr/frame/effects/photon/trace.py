"""`photon_trace`: photons from the scene's lights through the BVH (glsl/photon/trace.comp), once
per frame for both eyes. Lights emit in proportion to their power (`light_table`); each photon
path stores up to `bounces` photons on diffuse surfaces after the first hit (direct light is the
shadow rays' job), having passed through any number of mirror/glossy reflections (caustics), up to
MAX_REFLECTIONS in all (they do not count against `bounces`)."""
from __future__ import annotations

import moderngl
import numpy as np

from ....gl import shaders
from ....accel.gpu import DEFAULT_BINDING, layout_defines
from ...graph import Buffer, FramePlan, read, write
from ....gl.glsl_constants import declare
from ....gl.gpu_layout import SSBO, UNIT
from ...passes.prefix_scan import dispatch_shape
from ....scene.light_selection import LUMINANCE, light_flux
from .setup import PhotonPass, photon_setup
from ....accel import frustum  # noqa: F401  (declares TILE_SLACK, which photon/trace.comp reads)

TRACE_GROUP = declare("PHOTON_TRACE_GROUP", 64)  # photon paths a trace.comp group traces
# Mirror/glossy reflections one photon path may take on top of its diffuse bounces: a bound for
# facing mirrors (white metal reflects all), beyond the caustics a scene shows.
MAX_REFLECTIONS = 16


def light_power(scene, sphere_radius: float) -> np.ndarray:
    """(L, 3) emitted power (flux) per light (scene/light_selection.light_flux)."""
    return np.array([light_flux(l, sphere_radius) for l in scene.lights], np.float64).reshape(-1, 3)


def light_table(scene, paths: int, sphere_radius: float) -> np.ndarray:
    """(max(L, 1), 4) float32: the power one photon path from light l carries (flux / (p_l paths)),
    and the cumulative probability of picking lights 0..l; p_l is proportional to luminous power."""
    phi = light_power(scene, sphere_radius)
    table = np.zeros((max(len(phi), 1), 4), np.float32)
    lum = np.maximum(phi @ LUMINANCE, 0.0) if len(phi) else np.zeros(0)
    if lum.sum() <= 0:
        table[:, 3] = 1.0
        return table
    p = lum / lum.sum()
    with np.errstate(divide="ignore", invalid="ignore"):
        table[: len(phi), :3] = np.where(p[:, None] > 0, phi / (p[:, None] * max(paths, 1)), 0.0)
    table[: len(phi), 3] = np.cumsum(p)
    table[len(phi) - 1, 3] = 1.0
    return table


class PhotonTracePass(PhotonPass):
    name = "photon_trace"
    role = "one photon map per frame, both eyes"

    def io(self, plan: FramePlan) -> list:
        return [read("bvh"),
                write("photons", Buffer(lambda s: 32 * photon_setup(s).slots, "32 B per photon slot (paths x bounces)")),
                write("photon_trace.lights", Buffer(lambda s: 16 * max(len(s.scene.lights), 1), "16 B per light"))]

    def setup(self, gl, plan: FramePlan) -> None:
        # photon paths are closest-hit rays like reflections: the plan's layout for that ray kind
        self.layout = plan.traversal[2]
        self.program = shaders.compute(gl.ctx, "photon/trace.comp", layout_defines(DEFAULT_BINDING, self.layout))

    def execute(self, fc) -> None:
        ps = photon_setup(fc.sizing)
        lights = fc.resource("photon_trace.lights")
        lights.write(light_table(fc.scene, ps.paths, ps.sphere[3]).tobytes())
        fc.gpu_scene.bind()
        fc.gpu_scene.textures.use(UNIT["base_color_textures"])
        fc.accel.layout(self.layout).bind(DEFAULT_BINDING)
        lights.bind_to_storage_buffer(SSBO["photon_lights"])
        fc.resource("photons").bind_to_storage_buffer(SSBO["photons"])
        p = self.program
        values = {"photon_paths": ps.paths, "photon_stores": ps.stores, "photon_reflections": MAX_REFLECTIONS,
                  "photon_seed": ps.seed(fc.settings.seed),
                  "scene_sphere": ps.sphere}
        for k, v in values.items():
            if shaders.declares(p, k):
                p[k].value = v
        p.run(*dispatch_shape(ps.paths, TRACE_GROUP))
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()
