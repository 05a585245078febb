"""`dof`: thin-lens depth of field through screen-space rays (Widmer et al. 2015 §5.2;
glsl/post/dof.comp): each pixel's lens rays (RenderSettings dof_aperture, dof_focus,
dof_samples) from points of the lens disk through the pixel ray's point in focus, traced through
the frame's quadtree, gathering the frame's final colour where they meet the screen (the hit
pixel; behind a foreground object, the near side of the discontinuity: inpainting). Writes
`hdr_dof`, which tonemap then shows (passes/__init__.py radiance). Pinhole camera, stereo `dual`."""
from __future__ import annotations

from .. import shaders
from ..frame import FramePlan, Pass, Texture, read, write
from ..gpu_layout import IMAGE, SSBO
from . import scene_radiance
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .quadtree import set_tree_uniforms

THICKNESS = 0.02  # relative depth of each surface's slab: a lens ray deeper than that passed behind it
HDR_DOF = Texture("rgba32f")


class DofPass(Pass):
    name = "dof"

    def why(self, plan: FramePlan) -> str | None:
        return "depth of field (thin lens, screen-space rays)" if plan.dof else None

    def io(self, plan: FramePlan) -> list:
        return [read(scene_radiance(plan)[0]), read("gbuffer"), read("quadtree"), write("hdr_dof", HDR_DOF)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.source, fmt = scene_radiance(plan)
        self.program = shaders.compute(gl.ctx, "post/dof.comp", {"HDR_FORMAT": fmt, **camera_defines(plan)})

    def execute(self, fc) -> None:
        st, p = fc.settings, self.program
        set_eye_uniforms(p, fc)
        set_tree_uniforms(p, fc.gbuffer.size, fc.gbuffer.layers)
        for name, v in (("dof_aperture", float(st.dof_aperture)), ("dof_focus", float(st.dof_focus)),
                        ("dof_samples", int(st.dof_samples)), ("dof_thickness", THICKNESS),
                        ("frame_seed", int(st.seed))):
            if name in p:
                p[name].value = v
        fc.gbuffer.bind_for_reading()
        fc.resource("quadtree").bind_to_storage_buffer(SSBO["quadtree_nodes"])
        fc.resource(self.source).bind_to_image(IMAGE["dof_in"], read=True, write=False)
        fc.resource("hdr_dof").bind_to_image(IMAGE["dof_out"], read=False, write=True)
        dispatch_per_pixel(fc, p)

    def release(self) -> None:
        self.program.release()
