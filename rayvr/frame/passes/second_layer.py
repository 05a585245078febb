"""`second_layer`: the second depth layer the screen-space tracers see behind the first (Widmer et
al. 2015 §4.1; ssr `layers = 2`): per pixel, the nearest surface strictly behind the G-buffer's,
as "layer2" (rgba32f: the triangle's geometric normal facing the eye, view depth; 0 = none; the
quadtree's leaf planes, its only reader) and "layer2_triangle" (r32ui, NO_HIT = none). Two ways
(FramePlan.second_layer, RenderSettings second_layer), which `rayvr bench ssrt` times against
each other:

  rays  each pixel's camera ray continued through the BVH past its first hit (any triangle but
        the G-buffer's, further than its depth); glsl/gbuffer/second_layer.comp
  peel  depth peeling: the visibility raster again (gbuffer/peel.frag), fragments of the
        G-buffer's triangle or not behind its depth discarded, then the same compute resolve

Both resolve the layer the same way: the pixel ray's exact crossing of the triangle's plane and
its geometric normal turned to the eye (shading reads layer2_triangle)."""
from __future__ import annotations

import ctypes

from ...gl import shaders
from ...accel.gpu import DEFAULT_BINDING, GpuBvh
from ..graph import FramePlan, Pass, Texture, read, write
from ..gbuffer import layered_depth_target, delete_texture
from ...gl.gpu_layout import IMAGE, NO_HIT, UNIT
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .quadtree import uses_quadtree
from .visibility import VisibilityPass
from ...options import plan_part
from ...accel import frustum  # noqa: F401  (declares TILE_SLACK, which gbuffer/second_layer.comp reads)


LAYER2 = Texture("rgba32f")
LAYER2_TRIANGLE = Texture("r32ui")
GL_COLOR = 0x1800
# The material parameter by which an effect that uses the quadtree asks for its depth layers (ssr).
DEPTH_LAYERS = "layers"


def depth_layers(assignments) -> int:
    """Depth layers the frame's screen-space tracers need: 2 when a material of an effect that
    traces the quadtree asks for DEPTH_LAYERS = 2."""
    return max([int(a.params.get(DEPTH_LAYERS, 1)) for a in assignments if uses_quadtree(a.effect)] + [1])


class _PeelTarget:
    """The peel raster's own layered framebuffer: triangle IDs (r32ui) and a depth array."""

    def __init__(self, gl, size, layers):
        self.gl, self.size, self.layers = gl, tuple(size), layers
        self.triangle = gl.ctx.texture_array((*self.size, layers), 1, dtype="u4")
        self.fbo = gl.ctx.framebuffer([self.triangle])
        self.fbo.depth_mask = True  # the raw depth array below is unknown to moderngl
        self.depth_name = layered_depth_target(gl, self.fbo, self.size, layers)

    def clear(self) -> None:
        from ..gbuffer import GL_DEPTH, GL_FRAMEBUFFER
        raw = self.gl.raw
        self.fbo.use()
        raw.glBindFramebuffer(GL_FRAMEBUFFER, self.fbo.glo)
        raw.glClearBufferfv(GL_DEPTH, 0, (ctypes.c_float * 1)(0.0))
        raw.glClearBufferuiv(GL_COLOR, 0, (ctypes.c_uint * 4)(NO_HIT, 0, 0, 0))

    def attach_multiview(self) -> None:  # the peel never draws multiview (setup picks geometry)
        raise RuntimeError("the peel raster does not draw multiview")

    def release(self) -> None:
        self.gl.release_framebuffer(self.fbo)
        self.triangle.release()
        delete_texture(self.gl, self.depth_name)


class _PeelRaster(VisibilityPass):
    """The visibility raster with gbuffer/peel.frag, into a _PeelTarget."""

    fragment = "gbuffer/peel.frag"

    def setup(self, gl, plan: FramePlan) -> None:
        if plan.layer_mode == "multiview":  # gl_Layer is what the peel reads the first layer by
            from dataclasses import replace
            plan = replace(plan, layer_mode="geometry")
        super().setup(gl, plan)
        self.peel = None

    def target(self, fc):
        size, layers = fc.gbuffer.size, fc.gbuffer.layers
        if self.peel is None or (self.peel.size, self.peel.layers) != (tuple(size), layers):
            if self.peel is not None:
                self.peel.release()
            self.peel = _PeelTarget(self.gl, size, layers)
        return self.peel

    def release(self) -> None:
        if self.peel is not None:
            self.peel.release()
        super().release()


class SecondLayerPass(Pass):
    name = "second_layer"
    timed_kernels = True

    def why(self, plan: FramePlan) -> str | None:
        if plan.depth_layers < 2:
            return None
        return f"second depth layer for the screen-space tracers, by {plan.second_layer}"

    def io(self, plan: FramePlan) -> list:
        source = [read("bvh")] if plan.second_layer == "rays" else []
        return [read("gbuffer")] + source + [write("layer2", LAYER2), write("layer2_triangle", LAYER2_TRIANGLE)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.peeling = plan.second_layer == "peel"
        defines = {**camera_defines(plan), "SECOND_LAYER_PEEL": int(self.peeling)}
        if not self.peeling:
            defines.update(GpuBvh.defines(DEFAULT_BINDING))
        self.program = shaders.compute(gl.ctx, "gbuffer/second_layer.comp", defines)
        self.raster = None
        if self.peeling:
            self.raster = _PeelRaster()
            self.raster.setup(gl, plan)

    def execute(self, fc) -> None:
        fc.gbuffer.bind_for_reading()
        if self.peeling:
            fc.stage("peel", lambda: self.raster.execute(fc))
            self.raster.peel.triangle.use(UNIT["peel_triangle"])
        else:
            fc.accel.gpu.bind(DEFAULT_BINDING)
        set_eye_uniforms(self.program, fc)
        fc.gpu_scene.bind()
        fc.resource("layer2").bind_to_image(IMAGE["layer2"], read=False, write=True)
        fc.resource("layer2_triangle").bind_to_image(IMAGE["layer2_triangle"], read=False, write=True)
        fc.stage("resolve", lambda: dispatch_per_pixel(fc, self.program))

    def release(self) -> None:
        self.program.release()
        if self.raster is not None:
            self.raster.release()


def bind_second_layer(fc) -> None:
    """Bind layer2 and layer2_triangle for reading (UNIT_LAYER2*), if the frame has them."""
    if "layer2" in fc.resources:
        fc.resource("layer2").use(UNIT["layer2"])
        fc.resource("layer2_triangle").use(UNIT["layer2_triangle"])


@plan_part("second_layer", after=("primary",))
def second_layer_plan(ask, plan) -> None:
    """Peeling needs the raster's depth: with ray-cast primaries the second layer is ray-cast too."""
    plan["second_layer"] = ask.settings.second_layer if plan["primary"] == "raster" else "rays"
