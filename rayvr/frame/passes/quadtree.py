"""`quadtree`: the screen-space quadtree of Widmer et al. 2015 (rayvr/accel/quadtree.py) built from
the G-buffer every frame, one dispatch per level (glsl/ssrt/quadtree_build.comp), both eyes at
once; and `QuadtreeTracer`, which builds it for a rendered frame and traces ray batches through
it (glsl/ssrt/quadtree_batch.comp) for tests and benchmarks.

The pass is a core one (frame/passes/__init__.py): `why()` offers it to plans with an effect that says
`uses_quadtree = True` (ssr) or the view "quadtree_visits", with a pinhole camera (S is the planar
projection's space); the graph keeps it when a pass reads "quadtree" (binds it at
SSBO["quadtree_nodes"], calls `set_tree_uniforms` and `set_eye_uniforms`, and includes
glsl/ssrt/quadtree.glsl). An effect's own `QuadtreePass()` among its `passes()` is that core pass.
`QuadtreeVisitsPass` draws the nodes each pixel's mirror ray tests."""
from __future__ import annotations


import moderngl
import numpy as np

from ...gl import shaders
from ...accel.quadtree import (MAX_LEVELS, level_offsets, level_sizes, quadtree_bytes,
                              set_level_uniforms, unflatten, time_build_and_trace, trace_screen_rays)
from ..cameras import CAMERA_MODELS
from ..effect_registry import EFFECTS
from ..graph import Buffer, FramePlan, Pass, read, write
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO, UNIT
from .compute import camera_defines, set_eye_uniforms
from ...options import PlanRefusal, plan_part


# The material parameters by which an effect that uses the quadtree (`uses_quadtree`) sets its
# proxy-plane merge thresholds, where it declares them (ssr): a cosine, a relative depth error.
GAMMA_NORM, GAMMA_DIST = "gamma_norm", "gamma_dist"
LOCAL = declare("QT_BUILD_LOCAL", 8)  # quadtree_build.comp's local size (x and y)
QUADTREE = Buffer(lambda s: quadtree_bytes(s.size[0], s.size[1], s.layers * s.depth_layers),
                  "8 B per node: ceil(W/2^k) x ceil(H/2^k) nodes on every level k up to 1 x 1, per eye and depth layer",
                  max_extent=1 << (MAX_LEVELS - 1))


def uses_quadtree(effect: str) -> bool:
    """Whether the registered effect `effect` traces its rays through the quadtree (its declared trait)."""
    return getattr(EFFECTS.get(effect), "uses_quadtree", False)


def screen_space_refusal(effects, camera_name: str) -> str | None:
    """Why `effects` cannot render through the camera model `camera_name`, or None: screen-space
    tracing marches a planar projection's depth, which only the pinhole's G-buffer has (the
    quadtree pass is left out for the other models)."""
    users = sorted(e for e in effects if uses_quadtree(e))
    if not users or CAMERA_MODELS[camera_name].rasterizable:
        return None
    return (f"screen-space tracing ({', '.join(users)}) marches the pinhole's depth buffer, and the {camera_name} "
            f"camera is not a pinhole: give those materials `reflections` or `glossy` (traced in the BVH), or use the "
            f"pinhole camera")


@plan_part("screen_space")
def screen_space_plan(ask, plan) -> None:
    """No field: a frame whose effects trace the screen refuses a camera without the pinhole's depth."""
    refusal = screen_space_refusal(ask.effects, ask.camera.name)
    if refusal:
        raise PlanRefusal(refusal)  # the reason says what to change


def set_tree_uniforms(program, size, eyes: int) -> None:
    """qt_level, qt_top, qt_layer_nodes, qt_eyes of glsl/ssrt/quadtree.glsl for `eyes` eye images
    of `size` (tree layer = depth layer x eyes + eye)."""
    set_level_uniforms(program, size, "qt", "qt_layer_nodes")
    if shaders.declares(program, "qt_eyes"):
        program["qt_eyes"].value = int(eyes)


class QuadtreeBuilder:
    """The build program and its per-level dispatches (shared by the pass and QuadtreeTracer)."""

    def __init__(self, ctx, camera_model_defines: dict | None = None, depth_layers: int = 1):
        self.depth_layers = depth_layers
        self.program = shaders.compute(ctx, "ssrt/quadtree_build.comp",
                                       {**(camera_model_defines or {}), "QT_DEPTH_LAYERS": depth_layers})

    def build(self, ctx, gbuffer, scene, nodes: moderngl.Buffer, gamma_norm: float, gamma_dist: float, stage=None,
              layer2=None, gamma_adapt: float = 0.0) -> None:
        """Fill `nodes` from `gbuffer` (bound for reading here) and, with two depth layers, from the
        `layer2` texture (frame/passes/second_layer.py); the leaves' planes are the pixels' triangles', whose
        vertices come from `scene` (the GpuScene, bound here); camera uniforms must be set."""
        prog = self.program
        scene.bind()
        w, h = gbuffer.size
        set_tree_uniforms(prog, (w, h), gbuffer.layers)
        if self.depth_layers > 1:
            layer2.use(UNIT["layer2"])
        for name, v in (("gamma_norm", gamma_norm), ("gamma_dist", gamma_dist), ("gamma_adapt", gamma_adapt)):
            if shaders.declares(prog, name):
                prog[name].value = float(v)
        gbuffer.bind_for_reading()
        nodes.bind_to_storage_buffer(SSBO["quadtree_nodes"])
        for k, (wk, hk) in enumerate(level_sizes(w, h)):
            def run(k=k, wk=wk, hk=hk):
                prog["qt_build_level"].value = k
                prog.run((wk + LOCAL - 1) // LOCAL, (hk + LOCAL - 1) // LOCAL, gbuffer.layers * self.depth_layers)
                ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)  # level k + 1 reads it
            (stage or (lambda name, fn: fn()))(f"level{k}", run)

    def release(self) -> None:
        self.program.release()


class QuadtreePass(Pass):
    """Reads the G-buffer, writes "quadtree". `gamma_norm` (a cosine) and `gamma_dist` (relative
    depth): the proxy-plane thresholds; the defaults (1, 0) build the lossless tree. Each frame the
    strictest thresholds the effects that use the quadtree ask for take their place: their frame
    parameters GAMMA_NORM and GAMMA_DIST (where they declare them), reduced over their materials."""

    name = "quadtree"
    timed_kernels = True

    def __init__(self, gamma_norm: float = 1.0, gamma_dist: float = 0.0):
        self.gamma_norm, self.gamma_dist = gamma_norm, gamma_dist

    def thresholds(self, assignments) -> tuple[float, float]:
        effects = sorted({a.effect for a in assignments if uses_quadtree(a.effect) and GAMMA_NORM in a.params})
        if not effects:
            return self.gamma_norm, self.gamma_dist
        # each effect's frame parameters (its reducers over its materials), the strictest of the effects
        values = [EFFECTS[e].frame_values([(a.rule, a.params) for a in assignments if a.effect == e]) for e in effects]
        return max(v[GAMMA_NORM] for v in values), min(v[GAMMA_DIST] for v in values)

    def why(self, plan: FramePlan) -> str | None:
        users = [e for e in sorted(plan.effects) if uses_quadtree(e)]
        if plan.view == "quadtree_visits":
            users.append("view quadtree_visits")
        if plan.stereo == "warp":
            users.append("stereo warp")
        if plan.dof:
            users.append("depth of field")
        # Planes in S and straight rays need a planar projection: the pinhole's G-buffer only.
        if not users or not CAMERA_MODELS[plan.camera].rasterizable:
            return None
        return f"screen-space tracing ({', '.join(users)})"

    def io(self, plan: FramePlan) -> list:
        second = [read("layer2")] if plan.depth_layers > 1 else []
        return [read("gbuffer")] + second + [write("quadtree", QUADTREE)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.builder = QuadtreeBuilder(gl.ctx, camera_defines(plan), plan.depth_layers)

    def execute(self, fc) -> None:
        set_eye_uniforms(self.builder.program, fc)
        gamma_norm, gamma_dist = self.thresholds(fc.gpu_scene.assignments)
        layer2 = fc.resource("layer2") if self.builder.depth_layers > 1 else None
        self.builder.build(fc.gl.ctx, fc.gbuffer, fc.gpu_scene, fc.resource("quadtree"), gamma_norm, gamma_dist, stage=fc.stage,
                           layer2=layer2, gamma_adapt=fc.settings.quadtree_adapt)

    def release(self) -> None:
        self.builder.release()


class QuadtreeVisitsPass(Pass):
    """View "quadtree_visits": per pixel, the nodes its mirror ray tests in the quadtree (the
    thresholds of the scene's ssr materials, else lossless) as an 8-bit image
    (glsl/ssrt/visits_view.comp: red = the exact count up to 255, green/blue a heat ramp)."""

    name = "quadtree_visits"

    def why(self, plan: FramePlan) -> str | None:
        shown = plan.view == "quadtree_visits" and CAMERA_MODELS[plan.camera].rasterizable
        return "view = quadtree_visits" if shown else None

    def io(self, plan: FramePlan) -> list:
        from .tonemap import LDR
        return [read("gbuffer"), read("quadtree"), write("ldr", LDR)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "ssrt/visits_view.comp", camera_defines(plan))

    def execute(self, fc) -> None:
        from ...gl.gpu_layout import IMAGE
        from .compute import dispatch_per_pixel

        set_eye_uniforms(self.program, fc)
        set_tree_uniforms(self.program, fc.gbuffer.size, fc.gbuffer.layers)
        fc.gbuffer.bind_for_reading()
        fc.resource("quadtree").bind_to_storage_buffer(SSBO["quadtree_nodes"])
        fc.resource("ldr").bind_to_image(IMAGE["ldr"], read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()


class QuadtreeTracer:
    """Builds the quadtree of a renderer's last frame and traces ray batches through it on the
    GPU. Uses the Renderer's public API only: `render()` first, then `build()`, then `trace()`.

        tracer = QuadtreeTracer(renderer)
        renderer.render(rig, aux=())
        tracer.build(rig, gamma_norm=1.0, gamma_dist=0.0)
        status, nodes, pixel, point = tracer.trace(origins, directions, eye=0)

    With `depth_layers` = 2 the frame must have had the second layer (a material of ssr with
    layers = 2): tree layers 2 and 3 are then the eyes' second depth layer, and `trace_layers`
    traces through both (§4.1).
    """

    def __init__(self, renderer, depth_layers: int = 1):
        self.renderer = renderer
        self.ctx = renderer.gl.ctx
        self.depth_layers = depth_layers
        self.builder = QuadtreeBuilder(self.ctx, depth_layers=depth_layers)
        self.program = shaders.compute(self.ctx, "ssrt/quadtree_batch.comp")
        self.nodes: moderngl.Buffer | None = None
        self.size = None
        self._eye_values = None

    def build(self, rig, eyes: str = "both", gamma_norm: float = 1.0, gamma_dist: float = 0.0,
              gamma_adapt: float = 0.0) -> None:
        """Build the tree of the last rendered frame (rendered with `rig` and `eyes`); `gamma_adapt`:
        the distance-adaptive thresholds (accel/quadtree.py adaptive_thresholds)."""
        gbuffer = self.renderer.resource("gbuffer")
        eye_views = rig.eyes(eyes)
        self._eye_values = eye_views[0].camera.uniforms(eye_views, self.renderer.scene.origin)
        nbytes = quadtree_bytes(*gbuffer.size, gbuffer.layers * self.depth_layers)
        if self.nodes is None or self.nodes.size != nbytes:
            if self.nodes is not None:
                self.nodes.release()
            self.nodes = self.ctx.buffer(reserve=nbytes)
        self.size, self.layers = tuple(gbuffer.size), gbuffer.layers
        self._set_eyes(self.builder.program)
        self.builder.build(self.ctx, gbuffer, self.renderer.gpu_scene, self.nodes, gamma_norm, gamma_dist, layer2=self._layer2(),
                           gamma_adapt=gamma_adapt)
        self.ctx.finish()

    def _layer2(self):
        return self.renderer.resource("layer2") if self.depth_layers > 1 else None

    def _set_eyes(self, program) -> None:
        for name, value in self._eye_values.items():
            if shaders.declares(program, name):
                program[name].write(np.ascontiguousarray(value).tobytes())

    def levels(self, layer: int = 0) -> list[np.ndarray]:
        """The built tree of one tree layer (depth layer x eyes + eye), read back: (h_k, w_k, 2)
        uint32 per level, leaves first."""
        per_layer = level_offsets(level_sizes(*self.size))[1]
        flat = np.frombuffer(self.nodes.read(), np.uint32).reshape(-1, 2)
        return unflatten(flat[layer * per_layer:(layer + 1) * per_layer], self.size)

    def trace(self, origins, directions, eye=0):
        """Trace scene-local rays in layer `eye` (an int or one per ray) as a height field. Returns
        status (N,) uint32, nodes (N,) uint32, pixel (N, 2) int32 (GL pixel; -1 when no hit), point
        (N, 3) float32 (in S)."""
        return self.trace_layers(origins, directions, eye)[:4]

    def trace_layers(self, origins, directions, eye=0, layers: int = 1, thickness: float = 3.0e38,
                     start_level: int = MAX_LEVELS):
        """qt_trace_layers through `layers` depth layers with slabs of relative `thickness`, walks
        starting on `start_level`: what trace() returns, and the depth layer hit (N,) int32 (-1 for none)."""
        out = trace_screen_rays(self.ctx, self.program, origins, directions, eye,
                                lambda rbuf, obuf, n: self._bind(rbuf, obuf, n, layers, thickness, start_level))
        return (out[:, 0].copy(), out[:, 1].copy(), out[:, 2:4].view(np.int32).copy(),
                out[:, 4:7].view(np.float32).copy(), out[:, 7].view(np.int32).copy())

    def _bind(self, rbuf, obuf, n: int, layers: int = 1, thickness: float = 3.0e38,
              start_level: int = MAX_LEVELS) -> None:
        if layers > self.depth_layers:
            raise ValueError(f"{layers} depth layers asked of a tree built with {self.depth_layers}")
        set_tree_uniforms(self.program, self.size, self.layers)
        for name, v in (("trace_layers", int(layers)), ("trace_thickness", float(thickness)),
                        ("qt_start", int(start_level))):
            if shaders.declares(self.program, name):
                self.program[name].value = v
        self._set_eyes(self.program)
        self.nodes.bind_to_storage_buffer(SSBO["quadtree_nodes"])
        rbuf.bind_to_storage_buffer(SSBO["quadtree_rays"])
        obuf.bind_to_storage_buffer(SSBO["quadtree_results"])
        self.program["ray_count"].value = n

    def time(self, rig, origins, directions, eye=0, gamma_norm: float = 1.0, gamma_dist: float = 0.0,
             repeats: int = 10, min_seconds: float = 1.0, gamma_adapt: float = 0.0, layers: int = 1,
             thickness: float = 3.0e38, start_level: int = MAX_LEVELS) -> dict:
        """GPU ms of the build (all levels, all layers) and of tracing the rays (already on the GPU;
        trace_layers' options), after the times settle (timing.settle); median of 5 batches of
        `repeats` each. llvmpipe's timer queries read ~0 for compute: there the wall time per
        dispatch stands in."""
        gbuffer = self.renderer.resource("gbuffer")

        def build() -> None:
            self._set_eyes(self.builder.program)
            self.builder.build(self.ctx, gbuffer, self.renderer.gpu_scene, self.nodes, gamma_norm, gamma_dist, layer2=self._layer2(),
                               gamma_adapt=gamma_adapt)

        self.build(rig, "both" if gbuffer.layers == 2 else "left", gamma_norm, gamma_dist, gamma_adapt)
        return time_build_and_trace(self.ctx, self.program, origins, directions, eye, build,
                                    lambda rbuf, obuf, n: self._bind(rbuf, obuf, n, layers, thickness, start_level),
                                    repeats, min_seconds)

    def release(self) -> None:
        self.builder.release()
        self.program.release()
        if self.nodes is not None:
            self.nodes.release()
