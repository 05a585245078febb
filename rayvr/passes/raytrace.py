"""Ray-traced passes: the scene BVH, ray-traced primary visibility, per-effect pixel lists and
the effects `shadows`, `reflections`, `glossy` (glsl/rt/).

    bvh           builds and uploads the scene's BVH once (rayvr/accel/scene.py)
    primary_rays  camera rays through the BVH -> triangle IDs for the G-buffer resolve
    classify      G-buffer effect channel -> one pixel list per traced effect + dispatch sizes
    rt_<effect>   indirect dispatch over that effect's list, both eyes; overwrites its pixels of
                  the HDR colour the raster `shade` pass wrote (which skips those pixels)

Each declares `needed()` only for plans whose effects (or `primary == "rays"`) use it, so an
all-`raster` scene schedules none of them and never builds a BVH.
"""
from __future__ import annotations

import moderngl
import numpy as np

from .. import shaders
from ..accel.gpu import DEFAULT_BINDING, GpuBvh
from ..frame import FramePlan, Pass
from ..materials import EFFECTS
from .compute import dispatch_per_pixel, set_eye_uniforms

TRACED_EFFECTS = ("shadows", "reflections", "glossy")  # list slot = position here
LISTS_BINDING, ARGS_BINDING = 10, 11  # glsl/rt/pixel_list.glsl
ARGS_BYTES = 16  # per list: uvec4 (groups x, groups y, groups z, pixel count)
MAX_EFFECT_ID = 8


def traced_effects(plan: FramePlan) -> list[str]:
    return [e for e in TRACED_EFFECTS if e in plan.effects]


def needs_bvh(plan: FramePlan) -> bool:
    return plan.primary == "rays" or bool(traced_effects(plan))


def rt_defines() -> dict:
    table = [-1] * MAX_EFFECT_ID
    for slot, name in enumerate(TRACED_EFFECTS):
        table[EFFECTS[name].id] = slot
    return {**GpuBvh.defines(DEFAULT_BINDING), "RT_SLOTS": len(TRACED_EFFECTS),
            "RT_SLOT_TABLE": f"int[{MAX_EFFECT_ID}]({', '.join(map(str, table))})",
            "EFFECT_SHADOWS": EFFECTS["shadows"].id, "EFFECT_REFLECTIONS": EFFECTS["reflections"].id,
            "EFFECT_GLOSSY": EFFECTS["glossy"].id}


class PixelLists:
    """One list of packed pixels per traced effect, each sized for every pixel of every eye,
    plus the indirect-dispatch arguments; lives in the frame's targets (released with them)."""

    def __init__(self, ctx, capacity: int):
        self.capacity = capacity
        self.pixels = ctx.buffer(reserve=max(capacity, 1) * 4 * len(TRACED_EFFECTS))
        self.args = ctx.buffer(reserve=ARGS_BYTES * len(TRACED_EFFECTS))

    def bind(self) -> None:
        self.pixels.bind_to_storage_buffer(LISTS_BINDING)
        self.args.bind_to_storage_buffer(ARGS_BINDING)

    def counts(self) -> dict:
        """Pixels per traced effect in the last classified frame (reads back; for tests and stats)."""
        a = np.frombuffer(self.args.read(), np.uint32).reshape(-1, 4)
        return {e: int(a[i, 3]) for i, e in enumerate(TRACED_EFFECTS)}

    def release(self) -> None:
        self.pixels.release()
        self.args.release()


def pixel_lists(fc) -> PixelLists:
    w, h = fc.gbuffer.size
    capacity = w * h * fc.gbuffer.layers
    lists = fc.targets.get("rt_lists")
    if lists is None or lists.capacity != capacity:
        if lists is not None:
            lists.release()
        lists = fc.targets["rt_lists"] = PixelLists(fc.gl.ctx, capacity)
    return lists


class BvhPass(Pass):
    name = "bvh"
    writes = ("bvh",)

    def needed(self, plan: FramePlan) -> bool:
        return needs_bvh(plan)

    def execute(self, fc) -> None:
        fc.accel.ensure()  # built and uploaded on the first frame only


class PrimaryRaysPass(Pass):
    """The ray-traced alternative to the visibility raster (RenderSettings.primary = "rays")."""

    name = "primary_rays"
    reads = ("bvh",)
    writes = ("visibility",)

    def needed(self, plan: FramePlan) -> bool:
        return plan.primary == "rays"

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "rt/primary.comp", rt_defines())

    def execute(self, fc) -> None:
        set_eye_uniforms(self.program, fc)
        fc.accel.gpu.bind(DEFAULT_BINDING)
        gb = fc.gbuffer
        gb.textures["position"].bind_to_image(0, read=False, write=True)
        gb.textures["triangle"].bind_to_image(5, read=False, write=True)
        dispatch_per_pixel(fc, self.program)

    def release(self) -> None:
        self.program.release()


class ClassifyPass(Pass):
    name = "classify"
    reads = ("gbuffer",)
    writes = ("rt_lists",)

    def needed(self, plan: FramePlan) -> bool:
        return plan.view == "color" and bool(traced_effects(plan))

    def setup(self, gl, plan: FramePlan) -> None:
        self.program = shaders.compute(gl.ctx, "rt/classify.comp", rt_defines())
        self.finalize = shaders.compute(gl.ctx, "rt/classify.comp", {**rt_defines(), "FINALIZE": 1})

    def execute(self, fc) -> None:
        lists = pixel_lists(fc)
        lists.args.clear()
        lists.bind()
        fc.gbuffer.bind_for_reading()
        self.program["rt_capacity"].value = lists.capacity
        dispatch_per_pixel(fc, self.program)
        self.finalize.run(1, 1, 1)
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()
        self.finalize.release()


class TraceEffectPass(Pass):
    reads = ("gbuffer", "bvh", "rt_lists", "hdr")
    writes = ("hdr",)

    def __init__(self, effect: str):
        self.effect = effect
        self.slot = TRACED_EFFECTS.index(effect)
        self.name = f"rt_{effect}"

    def needed(self, plan: FramePlan) -> bool:
        return plan.view == "color" and self.effect in plan.effects

    def setup(self, gl, plan: FramePlan) -> None:
        defines = {**rt_defines(), "EFFECT": EFFECTS[self.effect].id, "RT_SLOT": self.slot}
        self.program = shaders.compute(gl.ctx, "rt/effects.comp", defines)

    def execute(self, fc) -> None:
        p = self.program
        set_eye_uniforms(p, fc)
        lists = pixel_lists(fc)
        values = {"ambient": tuple(fc.settings.ambient), "background": tuple(fc.settings.background),
                  "frame_seed": int(getattr(fc.settings, "seed", 0)), "rt_capacity": lists.capacity}
        for k, v in values.items():
            if k in p:
                p[k].value = v
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()
        fc.gpu_scene.textures.use(7)
        fc.accel.gpu.bind(DEFAULT_BINDING)
        lists.bind()
        fc.target("hdr").bind_to_image(0, read=False, write=True)
        p.run_indirect(lists.args, offset=self.slot * ARGS_BYTES)
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()


def all_rt_passes() -> dict:
    """name -> pass, for the renderer's registration list."""
    return {"bvh": BvhPass(), "primary_rays": PrimaryRaysPass(), "classify": ClassifyPass(),
            **{f"rt_{e}": TraceEffectPass(e) for e in TRACED_EFFECTS}}
