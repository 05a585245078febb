"""`visibility`: the layered visibility raster (triangle ID + reversed-Z depth), both eyes in one
draw (gl_Layer from the vertex or geometry stage, or GL_OVR_multiview2) or one draw per eye."""
from __future__ import annotations

import numpy as np

from ...gl import shaders
from ..graph import FramePlan, GBufferChannels, Pass, write
from ...gl.limits import to_float32
from ...render_options.visibility import LAYER_MODES

GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE, GL_ZERO_TO_ONE = 0x8CA1, 0x935E, 0x935F
LAYER_MODE_DEFINE = {"vertex": 0, "passes": 0, "geometry": 1, "multiview": 2}


def pick_layer_mode(gl, requested: str = "auto") -> str:
    """'vertex' writes gl_Layer from the vertex stage (instanced); 'geometry' uses a geometry
    shader; 'multiview' uses GL_OVR_multiview2; 'passes' draws each eye separately (the
    baseline the benchmark compares with)."""
    if requested != "auto":
        if requested not in LAYER_MODES:
            raise ValueError(f"unknown layer mode {requested!r}; allowed: auto, {', '.join(LAYER_MODES)}")
        if requested == "multiview" and not gl.has_extension("GL_OVR_multiview2"):
            raise ValueError("layer mode 'multiview' needs GL_OVR_multiview2, which this driver lacks")
        return requested
    if gl.has_extension("GL_ARB_shader_viewport_layer_array") or gl.has_extension("GL_AMD_vertex_shader_layer"):
        return "vertex"
    return "geometry"


class VisibilityPass(Pass):
    name = "visibility"
    fragment = "gbuffer/visibility.frag"  # frame/passes/second_layer.py peels with its own

    def target(self, fc):
        """What the draw renders into: clear(), size, attach_multiview() (the G-buffer)."""
        return fc.gbuffer

    def why(self, plan: FramePlan) -> str | None:
        if plan.primary != "raster":
            return None  # frame/passes/primary_rays.py casts them instead
        return f"primary visibility = raster ({plan.camera} camera, layers by {plan.layer_mode})"

    def io(self, plan: FramePlan) -> list:
        return [write("visibility", GBufferChannels(("depth", "triangle")))]

    def setup(self, gl, plan: FramePlan) -> None:
        self.gl = gl
        self.mode = plan.layer_mode
        self.clip_control = gl.raw.has("glClipControl") and (
            gl.ctx.version_code >= 450 or gl.has_extension("GL_ARB_clip_control"))
        # Multiview renders exactly LAYERS views; one eye uses the instanced path.
        self.mode = "vertex" if (self.mode == "multiview" and plan.eyes != 2) else self.mode
        defines = {"LAYER_MODE": LAYER_MODE_DEFINE[self.mode], "LAYERS": plan.eyes}
        self.program = shaders.program(gl.ctx, "gbuffer/visibility.vert", self.fragment,
                                       "gbuffer/visibility.geom" if self.mode == "geometry" else None, defines)
        self.vao = None
        self._scene = None

    def _vao(self, gpu_scene):
        if self._scene is not gpu_scene:
            if self.vao is not None:
                self.vao.release()
            self.vao = self.gl.ctx.vertex_array(self.program, [(gpu_scene.vbo, "3f 20x", "in_position")],
                                                index_buffer=gpu_scene.ibo, index_element_size=4)
            self._scene = gpu_scene
        return self.vao

    def execute(self, fc) -> None:
        ctx, raw = self.gl.ctx, self.gl.raw
        gb = self.target(fc)
        vp = np.zeros((2, 4, 4))
        for i, eye in enumerate(fc.eyes):
            vp[i] = eye.view_projection(fc.scene.origin, zero_to_one=self.clip_control).T  # column-major
        self.program["view_proj"].write(to_float32("view-projection matrix", vp).tobytes())
        vao = self._vao(fc.gpu_scene)
        if self.mode == "multiview":
            gb.attach_multiview()
        gb.clear()
        ctx.enable_only(ctx.DEPTH_TEST)
        ctx.depth_func = ">"  # reversed-Z: nearer is larger
        if self.clip_control:
            raw.glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE)
        ctx.viewport = (0, 0, *gb.size)
        try:
            if self.mode == "passes":
                for layer in range(len(fc.eyes)):
                    self.program["base_layer"].value = layer
                    vao.render(ctx.TRIANGLES, instances=1)
            else:
                if shaders.declares(self.program, "base_layer"):  # multiview shaders have no layer uniform
                    self.program["base_layer"].value = 0
                instanced = self.mode == "vertex"
                vao.render(ctx.TRIANGLES, instances=len(fc.eyes) if instanced else 1)
        finally:
            if self.clip_control:
                raw.glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE)
            ctx.depth_func = "<"

    def release(self) -> None:
        if self.vao is not None:
            self.vao.release()
        self.program.release()
