"""Ray-traced passes: the scene BVH, ray-traced primary visibility, per-effect pixel lists and
the effects `shadows`, `reflections`, `glossy` (glsl/rt/).

    bvh           builds and uploads the scene's BVH once (rayvr/accel/scene.py)
    primary_rays  camera rays through the BVH -> triangle IDs for the G-buffer resolve
    classify      G-buffer effect channel -> one pixel list per traced effect + dispatch sizes
    rt_<effect>   indirect dispatches over that effect's list, both eyes, as a wavefront: shading
                  kernels (glsl/rt/wave_shade.comp) store rays, lean kernels (rt/wave_trace.comp)
                  trace them; overwrites its pixels of the HDR colour the raster `shade` pass wrote
                  (which skips those pixels)

Each declares `needed()` only for plans whose effects (or `primary == "rays"`) use it, so an
all-`raster` scene schedules none of them and never builds a BVH.
"""
from __future__ import annotations

import moderngl
import numpy as np

from .. import shaders
from ..accel.gpu import DEFAULT_BINDING, GpuBvh
from ..frame import FramePlan, Pass
from ..gbuffer import BASE_COLOR_TEXTURE_UNIT
from ..materials import EFFECTS
from .compute import dispatch_per_pixel, set_eye_uniforms

TRACED_EFFECTS = ("shadows", "reflections", "glossy")  # list slot = position here
LISTS_BINDING, ARGS_BINDING = 10, 11  # glsl/rt/pixel_list.glsl
ARGS_BYTES = 16  # per list: uvec4 (groups x, groups y, groups z, pixel count)
# After the lists' arguments: classify's running count per list and its finished-group ticket.
SCRATCH_BYTES = 4 * (len(TRACED_EFFECTS) + 1)
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
        # Zeroed once: the classify pass leaves its scratch counters at zero for the next frame.
        self.args = ctx.buffer(bytes(ARGS_BYTES * len(TRACED_EFFECTS) + SCRATCH_BYTES))

    def bind(self) -> None:
        self.pixels.bind_to_storage_buffer(LISTS_BINDING)
        self.args.bind_to_storage_buffer(ARGS_BINDING)

    def counts(self) -> dict:
        """Pixels per traced effect in the last classified frame (reads back; for tests and stats)."""
        a = np.frombuffer(self.args.read(ARGS_BYTES * len(TRACED_EFFECTS)), np.uint32).reshape(-1, 4)
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


# glsl/rt/classify.comp aggregation, best first: (CLASSIFY_BALLOT, the extension it needs)
BALLOT_MODES = {"khr": (1, "GL_KHR_shader_subgroup"), "arb": (2, "GL_ARB_shader_ballot"), "shared": (0, None)}


class ClassifyPass(Pass):
    """G-buffer effect channel -> the per-effect pixel lists and their indirect dispatch sizes, in
    one dispatch (glsl/rt/classify.comp). `ballot` picks the in-wave aggregation: "khr", "arb" or
    "shared" (no subgroup operations); None takes the first the context has whose shader builds."""

    name = "classify"
    reads = ("gbuffer",)
    writes = ("rt_lists",)

    def __init__(self, ballot: str | None = None, group: tuple[int, int] = (32, 16)):
        assert group[0] % 8 == 0 and group[1] % 8 == 0 and group[0] * group[1] <= 1024, group
        self.ballot, self.group, self.mode = ballot, group, None

    def needed(self, plan: FramePlan) -> bool:
        return plan.view == "color" and bool(traced_effects(plan))

    def setup(self, gl, plan: FramePlan) -> None:
        modes = [self.ballot] if self.ballot else list(BALLOT_MODES)
        gx, gy = self.group
        d = {**rt_defines(), "CLASSIFY_GROUP_X": gx, "CLASSIFY_GROUP_Y": gy, "CLASSIFY_INVOCATIONS": gx * gy}
        for mode in modes:
            value, ext = BALLOT_MODES[mode]
            if ext and not gl.has_extension(ext) and self.ballot is None:
                continue
            try:
                self.program = shaders.compute(gl.ctx, "rt/classify.comp", {**d, "CLASSIFY_BALLOT": value})
            except shaders.ShaderError:
                if mode == modes[-1]:
                    raise
                continue
            self.mode = mode
            return

    def execute(self, fc) -> None:
        lists = pixel_lists(fc)
        lists.bind()
        fc.gbuffer.bind_for_reading()
        self.program["rt_capacity"].value = lists.capacity
        (w, h), (gx, gy) = fc.gbuffer.size, self.group
        self.program.run((w + gx - 1) // gx, (h + gy - 1) // gy, fc.gbuffer.layers)
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()


# Wavefront buffers (glsl/rt/wave.glsl): bytes per path and per shadow slot.
PATH_BYTES, SLOT_BYTES = 80, 48
WAVE_BUFFER_BYTES = 1 << 30  # largest wavefront buffer: the device's storage-block limit or this


def _effect_params(fc, effect: str) -> dict:
    """The largest of each parameter over the materials that use `effect` (sizes the waves)."""
    out = {"bounces": 1, "samples": 1, "area_samples": 1}
    for a in fc.gpu_scene.assignments:
        if a.effect == effect:
            for k in out:
                out[k] = max(out[k], int(a.params.get(k, 1)))
    return out


class WaveBuffers:
    """Path states and shadow slots for `capacity` paths x `slots` shadow rays each."""

    def __init__(self, ctx, capacity: int, slots: int):
        self.key = (capacity, slots)
        self.paths = ctx.buffer(reserve=capacity * PATH_BYTES)
        self.shadows = ctx.buffer(reserve=capacity * slots * SLOT_BYTES)
        self.args = ctx.buffer(reserve=32)

    def bind(self) -> None:
        self.paths.bind_to_storage_buffer(WAVE_PATHS_BINDING)
        self.shadows.bind_to_storage_buffer(WAVE_SHADOWS_BINDING)
        self.args.bind_to_storage_buffer(WAVE_ARGS_BINDING)

    def release(self) -> None:
        for b in (self.paths, self.shadows, self.args):
            b.release()


WAVE_PATHS_BINDING, WAVE_SHADOWS_BINDING, WAVE_ARGS_BINDING = 12, 13, 14


def wave_plan(pixel_capacity: int, paths_per_pixel: int, slots: int, limit: int) -> tuple[int, int]:
    """(pixels per batch, shadow slots per chunk) so that no wavefront buffer exceeds `limit` bytes."""
    batch = max(1, min(pixel_capacity, limit // (PATH_BYTES * paths_per_pixel)))
    chunk = max(1, min(slots, limit // (SLOT_BYTES * batch * paths_per_pixel)))
    if chunk * SLOT_BYTES * batch * paths_per_pixel > limit:
        batch = max(1, limit // (SLOT_BYTES * paths_per_pixel))
    return batch, chunk


class TraceEffectPass(Pass):
    """One effect as a wavefront: shading kernels (rt/wave_shade.comp) write rays into buffers,
    lean kernels (rt/wave_trace.comp) trace them. Per batch of the effect's pixel list:
        prep; pixel event (+ shadow rays); then per bounce: closest hits, hit event (+ shadow
        rays); finish (fused into the last shadow kernel when a pixel has one path).
    The shadow rays of an event may be split into chunks and the pixel list into batches so
    that every buffer stays under the device's storage-block limit."""

    reads = ("gbuffer", "bvh", "rt_lists", "hdr")
    writes = ("hdr",)

    def __init__(self, effect: str):
        self.effect = effect
        self.slot = TRACED_EFFECTS.index(effect)
        self.name = f"rt_{effect}"
        self.stage_timer = None  # a PassTimer-like run(name, fn): per-kernel GPU times (profiling)

    def needed(self, plan: FramePlan) -> bool:
        return plan.view == "color" and self.effect in plan.effects

    def setup(self, gl, plan: FramePlan) -> None:
        d = {**rt_defines(), "EFFECT": EFFECTS[self.effect].id, "RT_SLOT": self.slot}
        trace = "rt/wave_trace.comp"
        self.programs = {
            "prep": shaders.compute(gl.ctx, trace, {**d, "WAVE_STAGE": 0}),
            "closest": shaders.compute(gl.ctx, trace, {**d, "WAVE_STAGE": 1}),
            "shadow": shaders.compute(gl.ctx, trace, {**d, "WAVE_STAGE": 2}),
            "shadow_finish": shaders.compute(gl.ctx, trace, {**d, "WAVE_STAGE": 2, "WAVE_FINISH": 1}),
            "pixel": shaders.compute(gl.ctx, "rt/wave_shade.comp", {**d, "WAVE_STAGE": 3}),
            "finish": shaders.compute(gl.ctx, "rt/wave_shade.comp", {**d, "WAVE_STAGE": 5}),
        }
        if self.effect != "shadows":
            self.programs["hit"] = shaders.compute(gl.ctx, "rt/wave_shade.comp", {**d, "WAVE_STAGE": 4})

    def _buffers(self, fc, capacity: int, slots: int) -> WaveBuffers:
        key = f"rt_wave_{self.effect}"
        buf = fc.targets.get(key)
        if buf is None or buf.key != (capacity, slots):
            if buf is not None:
                buf.release()
            buf = fc.targets[key] = WaveBuffers(fc.gl.ctx, capacity, slots)
        return buf

    def execute(self, fc) -> None:
        ctx = fc.gl.ctx
        lists = pixel_lists(fc)
        prm = _effect_params(fc, self.effect)
        traced = self.effect != "shadows"
        bounces = prm["bounces"] if traced else 0
        paths_per_pixel = prm["samples"] if self.effect == "glossy" else 1
        slots = sum(prm["area_samples"] if l.kind == "rect" else 1 for l in fc.scene.lights) or 1
        limit = min(int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or WAVE_BUFFER_BYTES), WAVE_BUFFER_BYTES)
        batch, chunk = wave_plan(lists.capacity, paths_per_pixel, slots, limit)
        capacity = batch * paths_per_pixel
        wave = self._buffers(fc, capacity, chunk)
        chunks = [(k, min(chunk, slots - k)) for k in range(0, slots, chunk)]
        common = {"ambient": tuple(fc.settings.ambient), "background": tuple(fc.settings.background),
                  "frame_seed": int(getattr(fc.settings, "seed", 0)), "rt_capacity": lists.capacity,
                  "wave_capacity": capacity, "wave_paths_per_pixel": paths_per_pixel}
        for p in self.programs.values():
            set_eye_uniforms(p, fc)
            for k, v in common.items():
                if k in p:
                    p[k].value = v
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()
        fc.gpu_scene.textures.use(BASE_COLOR_TEXTURE_UNIT)
        fc.accel.gpu.bind(DEFAULT_BINDING)
        lists.bind()
        wave.bind()
        fc.target("hdr").bind_to_image(0, read=False, write=True)
        barrier = ctx.memory_barrier

        def run(name, items=1, **uniforms):
            p = self.programs[name]
            for k, v in uniforms.items():
                if k in p:
                    p[k].value = v
            def go():
                if name == "prep":
                    p.run(1, 1, 1)
                else:
                    p.run_indirect(wave.args, offset=16 * items)
                barrier(moderngl.ALL_BARRIER_BITS)
            if self.stage_timer is None:
                go()
            else:
                self.stage_timer.run(f"{self.name}.{name}", go)

        one_path = paths_per_pixel == 1
        for base in range(0, lists.capacity, batch):
            for p in self.programs.values():
                if "wave_batch_base" in p:
                    p["wave_batch_base"].value = base
            run("prep")
            for ci, (first, count) in enumerate(chunks):
                last = ci == len(chunks) - 1
                run("pixel", 0, wave_slot_first=first, wave_slot_count=count)
                fuse = last and bounces == 0 and one_path
                run("shadow_finish" if fuse else "shadow", 0, wave_items=0, wave_slot_first=first, wave_slot_count=count)
            for b in range(bounces):
                run("closest", 1)
                for ci, (first, count) in enumerate(chunks):
                    last = ci == len(chunks) - 1
                    run("hit", 1, wave_bounce=b, wave_last_chunk=int(last), wave_slot_first=first, wave_slot_count=count)
                    fuse = last and b == bounces - 1 and one_path
                    run("shadow_finish" if fuse else "shadow", 1, wave_items=1)
            if not one_path:
                run("finish", 0)

    def release(self) -> None:
        for p in self.programs.values():
            p.release()


def all_rt_passes() -> dict:
    """name -> pass, for the renderer's registration list."""
    return {"bvh": BvhPass(), "primary_rays": PrimaryRaysPass(), "classify": ClassifyPass(),
            **{f"rt_{e}": TraceEffectPass(e) for e in TRACED_EFFECTS}}
