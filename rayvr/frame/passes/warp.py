"""Stereo `warp` (Widmer et al. 2015 §5.1, rayvr/frame/stereo.py): the frame renders and shades one
central view (between the eyes; a one-layer G-buffer, every effect as usual, then its quadtree),
and this pass synthesizes each eye from it by tracing the eye's camera rays through the central
quadtree (glsl/stereo/warp.comp, which includes glsl/ssrt/quadtree.glsl). Rays that pass behind a
foreground object (disocclusions) or leave the central image are holes: counted per eye and
inpainted from the background side. Writes the eyes' colour ("stereo_ldr", the frame's output:
alpha 0 marks a hole) and linear view depth ("stereo_depth").

With two depth layers (FramePlan.depth_layers, RenderSettings.warp_layers) a ray that passes
behind a first-layer surface continues on the central view's second layer (frame/passes/second_layer.py),
and a hit there is shaded from the scene like the `raster` rung.
"""
from __future__ import annotations

import moderngl
import numpy as np

from ...gl import shaders
from ..graph import Buffer, FramePlan, Pass, Texture, read, write
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import IMAGE, SSBO, TONEMAPPERS, UNIT
from ..stereo import WARP_DEPTH, WARP_OUTPUT
from .compute import TILE, camera_defines
from .quadtree import set_tree_uniforms

THICKNESS = 0.02  # each surface of the central view is a slab this deep (relative z); behind it: occluded
# Per eye: holes (passed behind every layer, left the image), hits on the first and the second depth
# layer, background, nodes tested; glsl/stereo/warp.comp counts kind k at WARP_COUNT_<K>.
COUNTS = ("disoccluded", "offscreen", "hits", "hits_second_layer", "background", "nodes")
for _index, _kind in enumerate(COUNTS):
    declare(f"WARP_COUNT_{_kind.upper()}", _index, uint=True)
declare("WARP_COUNTS", len(COUNTS))
WARP_COUNTS = Buffer(lambda s: 4 * len(COUNTS) * 2, "per eye: holes (disoccluded, off screen), hits per layer, "
                     "background, nodes tested")


def warp_counts(fc) -> dict:
    """Per eye of frame `fc` (reads back): pixels, holes by disocclusion and off screen, hits and
    the nodes their rays tested; "hole_fraction_<eye>" = holes / pixels."""
    a = np.frombuffer(fc.resource("warp_counts").read(), np.uint32).reshape(2, len(COUNTS))
    w, h = fc.gbuffer.size
    out = {}
    for i, eye in enumerate(fc.out_eyes):
        out.update({f"{k}_{eye.name}": int(a[i, j]) for j, k in enumerate(COUNTS)})
        out[f"pixels_{eye.name}"] = w * h
        out[f"hole_fraction_{eye.name}"] = (int(a[i, 0]) + int(a[i, 1])) / (w * h)
    return out


def read_holes(fc) -> np.ndarray:
    """(2, H, W) bool, rows top-down: the warped eyes' holes in frame `fc` (alpha 0; reads back)."""
    w, h = fc.gbuffer.size
    tex = fc.resource(WARP_OUTPUT)
    rgba = np.frombuffer(tex.read(), np.uint8).reshape(2, h, w, 4)[:, ::-1]
    return rgba[..., 3] == 0


class WarpPass(Pass):
    name = "warp"

    def __init__(self, thickness: float = THICKNESS):
        self.thickness = thickness

    def why(self, plan: FramePlan) -> str | None:
        return "stereo = warp" if plan.stereo == "warp" else None

    def io(self, plan: FramePlan) -> list:
        second = [read("layer2_triangle")] if plan.depth_layers > 1 else []  # its surfaces are shaded here
        return [read("gbuffer"), read("quadtree"), read("ldr")] + second + \
            [write(WARP_OUTPUT, Texture("rgba8", layers=2)), write(WARP_DEPTH, Texture("r32f", layers=2)),
             write("warp_counts", WARP_COUNTS)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.layers = plan.depth_layers
        self.program = shaders.compute(gl.ctx, "stereo/warp.comp", {**camera_defines(plan), "WARP_LAYERS": self.layers})
        # The counts are zeroed by a GPU copy, not written by the CPU every frame: a buffer the CPU
        # writes or reads every frame may live in host memory, where each of the pass's atomics
        # crosses the bus (what made the MSAA trace take 80 ms; frame/passes/primary_rays.py).
        self.zero = gl.ctx.buffer(bytes(WARP_COUNTS.nbytes(None)))

    def execute(self, fc) -> None:
        p = self.program
        center = fc.eyes[0]
        set_tree_uniforms(p, fc.gbuffer.size, 1)
        p["warp_thickness"].value = self.thickness
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()  # the hit pixels' triangles give the depth
        if self.layers > 1:  # second-layer hits are shaded from the scene (the raster rung)
            fc.gpu_scene.textures.use(UNIT["base_color_textures"])
            fc.resource("layer2_triangle").use(UNIT["layer2_triangle"])
            p["ambient"].value = tuple(fc.settings.ambient)
            p["exposure"].value = float(fc.settings.exposure)
            p["tonemapper"].value = TONEMAPPERS.index(fc.settings.tonemapper)
        fc.resource("quadtree").bind_to_storage_buffer(SSBO["quadtree_nodes"])
        counts = fc.resource("warp_counts")
        fc.gl.ctx.copy_buffer(counts, self.zero)
        counts.bind_to_storage_buffer(SSBO["warp_counts"])
        fc.resource("ldr").bind_to_image(IMAGE["ldr"], read=True, write=False)
        fc.resource(WARP_OUTPUT).bind_to_image(IMAGE["warp_color"], read=False, write=True)
        fc.resource(WARP_DEPTH).bind_to_image(IMAGE["warp_depth"], read=False, write=True)
        w, h = fc.gbuffer.size
        for layer, eye in enumerate(fc.out_eyes):
            # Camera slot 0: the central view (the tree's layer), slot 1: the eye being made.
            for name, value in center.camera.uniforms([center, eye], fc.scene.origin).items():
                if shaders.declares(p, name):
                    p[name].write(np.ascontiguousarray(value).tobytes())
            p["warp_layer"].value = layer
            p.run((w + TILE - 1) // TILE, (h + TILE - 1) // TILE, 1)
            fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()
        self.zero.release()
