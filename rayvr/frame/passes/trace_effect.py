"""`rt_<effect>`: a traced effect (shadows, reflections, glossy, path) as a wavefront over its pixel list,
both eyes at once: shading kernels (glsl/rt/wave_shade.comp, with the effect's own part included
from Effect.shader, e.g. glsl/effects/glossy.glsl) write rays into buffers, lean kernels
(rt/wave_trace.comp) trace them. Per batch of the effect's pixel list:
    prep; pixel event (+ shadow rays); then per bounce: closest hits, hit event (+ shadow rays);
    finish (fused into the last shadow kernel when a pixel has one path).
Each trace kernel (closest hits, shadow rays) may take its rays sorted by direction and origin
(--ray-order morton: frame/passes/ray_order.py) and as persistent threads (--persistent:
frame/passes/persistent_threads.py); either leaves every ray's result, and the image, as it was.
The shadow rays of an event may be split into chunks and the pixel list into batches so that no
buffer exceeds the device's storage-block limit. The pass composes its pixels of `hdr` over what
`shade` wrote."""
from __future__ import annotations

import moderngl

from ...gl import shaders
from ...accel.gpu import DEFAULT_BINDING, GpuBvh, layout_defines
from ..effect_registry import Effect, traced_effects
from ..graph import Buffer, FramePlan, Pass, Sizing, compose, read, write
from ...gl.gpu_layout import IMAGE, SSBO, UNIT
from ...scene.light_selection import shadow_rays_per_surface
from .classify import ARGS_BYTES as LIST_ARGS_BYTES, bind_lists, list_slots
from .compute import camera_defines, set_eye_uniforms, write_uniforms
from .persistent_threads import persistent_groups
from .quadtree import set_tree_uniforms
from .ray_order import ORDER_PATHS, ORDER_SHADOWS, RayOrder, pair_bytes, sort_table_bytes
from .second_layer import bind_second_layer

# The material parameters the wavefront reads by name, from an effect that declares them in `params`
# (keyed by these): the hit events after the pixel's (an effect whose rays go on, `follows_rays`), the
# paths per pixel, the points per rect light of the pixel's shadow rays (PARAM_AREA_SAMPLES) and of
# a reflection ray's hit (PARAM_HIT_AREA_SAMPLES; an effect without it lights hits as its pixels).
WAVE_BOUNCES, WAVE_SAMPLES, WAVE_AREA_SAMPLES = "bounces", "samples", "area_samples"
WAVE_HIT_AREA_SAMPLES = "hit_area_samples"
WAVE_PARAMS = (WAVE_BOUNCES, WAVE_SAMPLES, WAVE_AREA_SAMPLES, WAVE_HIT_AREA_SAMPLES)

# Wavefront buffers (glsl/rt/wave.glsl): bytes per path and per shadow slot; the args buffer: two
# indirect dispatches; the ray counters (closest hits, shadow rays) of count_rays.
PATH_BYTES, SLOT_BYTES = 80, 48
ARGS_BYTES, RAYS_BYTES = 32, 8
# Largest wavefront buffer: the device's storage-block limit or this (Sizing.wave_buffer_bytes, from
# Renderer(wave_buffer_bytes=...), gives another: tests split the waves with a small one).
WAVE_BUFFER_BYTES = 1 << 30
# The lean kernels that trace rays (rt/wave_trace.comp stages 1 and 2): ordered and fetched as the
# plan says; the others run one invocation per item.
SHADOW_KERNELS = ("shadow", "shadow_finish", "shadow_every", "shadow_finish_every")
TRACE_KERNELS = ("closest", *SHADOW_KERNELS)


def wave_plan(pixel_capacity: int, paths_per_pixel: int, slots: int, limit: int,
              hit_slots: int | None = None) -> tuple[int, int, int]:
    """(pixels per batch, shadow slots per chunk of a pixel event, of a hit event) so that no
    wavefront buffer exceeds `limit` bytes. A pixel event's slots are rows of the batch's pixels,
    a hit event's rows of its paths (`hit_slots`: a hit's shadow rays, default `slots`)."""
    hit_slots = slots if hit_slots is None else hit_slots
    batch = max(1, min(pixel_capacity, limit // (PATH_BYTES * paths_per_pixel)))
    if SLOT_BYTES * batch * paths_per_pixel > limit:  # not even one slot of every path fits
        batch = max(1, limit // (SLOT_BYTES * paths_per_pixel))
    pixel_chunk = max(1, min(slots, limit // (SLOT_BYTES * batch)))
    hit_chunk = max(1, min(hit_slots, limit // (SLOT_BYTES * batch * paths_per_pixel)))
    return batch, pixel_chunk, hit_chunk


def chunk_ranges(total: int, size: int) -> list:
    """(first, count) of consecutive chunks of `size` covering `total` slots."""
    return [(k, min(size, total - k)) for k in range(0, total, size)]


def hit_points(effect: Effect, params: dict) -> int:
    """Points per rect light where a reflection ray of a material with `params` lands, at most
    (glsl/rt/wave_shade.comp path_vertex_begin): `hit_area_samples`, or with 0 the pixel's
    `area_samples` spread over the rays it sends, at least one a ray. An effect whose `samples` may be
    0 (ssr: mirror pixels send one ray whatever it says) may send one: area_samples then."""
    area = int(params.get(WAVE_AREA_SAMPLES, 1))
    if WAVE_HIT_AREA_SAMPLES not in effect.params:  # its hits are lit as its pixels
        return area
    hit = int(params.get(WAVE_HIT_AREA_SAMPLES, effect.params[WAVE_HIT_AREA_SAMPLES].default))
    if hit > 0:
        return hit
    samples = effect.params.get(WAVE_SAMPLES)
    rays = int(params.get(WAVE_SAMPLES, 1)) if samples is not None and (samples.lo or 0) >= 1 else 1
    return max(-(-area // max(rays, 1)), 1)


def effect_maxima(assignments, effect: Effect) -> dict:
    """The largest of each integer parameter over the materials that use `effect` (sizes the waves);
    WAVE_HIT_AREA_SAMPLES: the largest hit_points."""
    out = dict.fromkeys(WAVE_PARAMS, 1)
    for a in assignments:
        if a.effect == effect.name:
            for k in out:
                value = hit_points(effect, a.params) if k == WAVE_HIT_AREA_SAMPLES else a.params.get(k, 1)
                out[k] = max(out[k], int(value))
    return out


def follows_rays(effect: Effect) -> bool:
    """Its rays go on past the pixel's surface for `bounces` hit events (reflections, glossy, path)."""
    return effect.reflective or effect.path_vertices


class WaveShape:
    """How an effect's wavefront is cut for one frame: batches, shadow chunks, path counts."""

    def __init__(self, effect: Effect, s: Sizing):
        prm = effect_maxima(s.assignments, effect)
        self.bounces = prm[WAVE_BOUNCES] if follows_rays(effect) else 0  # hit events after the pixel's
        self.paths_per_pixel = prm[WAVE_SAMPLES] if WAVE_SAMPLES in effect.params else 1
        lights = s.scene.lights if s.scene is not None else ()
        self.rect_lights = any(light.kind == "rect" for light in lights)

        def shadow_rays(per_rect: int) -> int:  # of one surface: per_rect points a rect light, 1 another
            return shadow_rays_per_surface(lights, per_rect, s.light_picks)
        per_path = prm[WAVE_SAMPLES] if effect.shader_defines.get("PIXEL_LIGHT_SAMPLES_PER_PATH") else 1
        self.slots = shadow_rays(prm[WAVE_AREA_SAMPLES] * per_path)
        # A hit event lights its surface with hit_points per rect light, never the pixel event's set
        # per path: its shadow rays fill the first hit_slots slots only.
        self.hit_slots = shadow_rays(prm[WAVE_HIT_AREA_SAMPLES])
        cap = s.wave_buffer_bytes or WAVE_BUFFER_BYTES
        limit = min(s.max_ssbo_bytes or cap, cap)
        self.capacity_pixels = s.pixels
        self.batch, self.chunk, self.hit_chunk = wave_plan(s.pixels, self.paths_per_pixel, self.slots, limit,
                                                           self.hit_slots)
        self.capacity = self.batch * self.paths_per_pixel  # paths the buffers hold

    def adaptive(self, probes: int) -> bool:
        """Whether adaptive shadows with `probes` (SHADOW_PROBES) may leave a ray untraced: only a rect
        light's run of points outnumbers its probes, and no run is longer than an event's slots."""
        return probes > 0 and self.rect_lights and max(self.slots, self.hit_slots) > probes

    @property
    def shadow_slots(self) -> int:
        """ShadowSlot records the shadow buffer holds: the larger of the two events' chunks."""
        return max(self.batch * self.chunk, self.capacity * self.hit_chunk)

    @property
    def chunks(self) -> list:
        """(first slot, count) of each chunk of the pixel event's shadow slots."""
        return chunk_ranges(self.slots, self.chunk)

    @property
    def hit_chunks(self) -> list:
        """The chunks a hit event's shadow rays fall in (the last one ends the path)."""
        return chunk_ranges(self.hit_slots, self.hit_chunk)

    @property
    def trace_kernels(self) -> int:
        """Trace kernels a batch runs: one per pixel-event chunk, then per bounce a closest-hit
        kernel and one per hit-event chunk (persistent threads: a ray counter each)."""
        return len(self.chunks) + self.bounces * (1 + len(self.hit_chunks))


class TraceEffectPass(Pass):
    timed_kernels = True
    count_rays = False  # count_rays(): the trace kernels add up the rays they trace

    def __init__(self, effect: Effect):
        self.effect = effect
        self.name = f"rt_{effect.name}"
        self.slot = [e.name for e in traced_effects()].index(effect.name)
        key = f"rt_wave.{effect.name}"
        self.buffers = {
            "paths": (f"{key}.paths", Buffer(lambda s: WaveShape(effect, s).capacity * PATH_BYTES,
                                             "80 B per path of a batch")),
            "shadows": (f"{key}.shadows", Buffer(lambda s: WaveShape(effect, s).shadow_slots * SLOT_BYTES,
                                                 "48 B per shadow ray of a batch's chunk")),
            "args": (f"{key}.args", Buffer(lambda s: ARGS_BYTES, "2 indirect dispatches")),
            "rays": (f"{key}.rays", Buffer(lambda s: RAYS_BYTES, "the ray counters of count_rays")),
        }
        # --ray-order morton: the (key, ray) pairs, their ping-pong copy, the sort's digit table
        self.order_buffers = {
            "pairs": (f"{key}.order", Buffer(lambda s: pair_bytes(WaveShape(effect, s).capacity),
                                             "8 B per path of a batch: (key, ray)")),
            "alt": (f"{key}.order_alt", Buffer(lambda s: pair_bytes(WaveShape(effect, s).capacity),
                                               "8 B per path of a batch (ping-pong)")),
            "table": (f"{key}.order_table", Buffer(lambda s: sort_table_bytes(WaveShape(effect, s).capacity),
                                                   "256 digit counts per 256 paths (+ scan totals)")),
        }
        # --persistent: one ray counter per trace kernel of a batch
        self.fetch_buffer = (f"{key}.fetch", Buffer(lambda s: 4 * WaveShape(effect, s).trace_kernels,
                                                    "4 B per trace kernel of a batch"))

    def why(self, plan: FramePlan) -> str | None:
        if plan.view != "color" or self.effect.name not in plan.effects:
            return None
        names = plan.materials_using(self.effect.name)
        return f"effect {self.effect.name}" + (f" ({', '.join(names)})" if names else "")

    def io(self, plan: FramePlan) -> list:
        screen = [read("quadtree")] if self.effect.uses_quadtree else []
        if self.effect.uses_quadtree and plan.depth_layers > 1:
            screen.append(read("layer2_triangle"))
        extra = list(self.order_buffers.values()) if plan.ray_order != "none" else []
        extra += [self.fetch_buffer] if plan.persistent else []
        return [read("gbuffer"), read("bvh"), read("rt_lists"), read("rt_list_args"), compose("hdr")] + screen + \
            [write(name, t) for name, t in list(self.buffers.values()) + extra]

    def setup(self, gl, plan: FramePlan) -> None:
        d = {**GpuBvh.defines(DEFAULT_BINDING), **self.effect.param_defines(), "EFFECT": self.effect.id, **self.effect.shader_defines,
             "RT_SLOT": self.slot, "EFFECT_PATHS": self.effect.shader, **camera_defines(plan)}
        self.shade_defines = d  # a subclass may compile variants of the shading kernels
        self.ray_order = RayOrder(gl.ctx, d) if plan.ray_order != "none" else None
        self.persistent = plan.persistent
        # how the trace kernels take their rays (rt/wave_fetch.glsl); prep zeroes the fetch counters
        fetch = {"WAVE_RAY_ORDER": int(self.ray_order is not None), "WAVE_PERSISTENT": int(self.persistent)}
        trace, shade = "rt/wave_trace.comp", "rt/wave_shade.comp"
        # The tracing kernels take the plan's layout for their ray kind; the shading kernels only
        # read triangles (the same buffer in every layout) and stay on the binary defines.
        _, shadow, reflect = plan.traversal
        self.layouts = {"closest": reflect, **dict.fromkeys(SHADOW_KERNELS, shadow)}
        ds, dr = ({**d, **layout_defines(DEFAULT_BINDING, x)} for x in (shadow, reflect))
        # the trace kernels' sources, so that count_rays() can build their counting variants
        self.trace_sources = {"closest": (trace, {**dr, **fetch, "WAVE_STAGE": 1, "QT_DEPTH_LAYERS": plan.depth_layers,
                                                  "SSR_TRACE": int(self.effect.uses_quadtree)}),
                              "shadow": (trace, {**ds, **fetch, "WAVE_STAGE": 2}),
                              "shadow_finish": (trace, {**ds, **fetch, "WAVE_STAGE": 2, "WAVE_FINISH": 1})}
        # every slot in a plain loop, where no light's run can outnumber its probes (WaveShape.adaptive):
        # built when a frame first needs them (a scene without rect lights never runs the adaptive ones)
        for name in ("shadow", "shadow_finish"):
            source, defines = self.trace_sources[name]
            self.trace_sources[f"{name}_every"] = (source, {**defines, "ADAPTIVE_SHADOWS": 0})
        self.ctx, self.counting = gl.ctx, {}  # count_rays' variants of the trace kernels, built on first use
        self.programs = {
            "prep": shaders.compute(gl.ctx, trace, {**d, **fetch, "WAVE_STAGE": 0}),
            **{name: shaders.compute(gl.ctx, *self.trace_sources[name]) for name in ("closest", "shadow", "shadow_finish")},
            "pixel": shaders.compute(gl.ctx, shade, {**d, "WAVE_STAGE": 3}),
            "finish": shaders.compute(gl.ctx, shade, {**d, "WAVE_STAGE": 5}),
        }
        if follows_rays(self.effect):
            self.programs["hit"] = shaders.compute(gl.ctx, shade, {**d, "WAVE_STAGE": 4})

    def frame_programs(self, every: str) -> dict:
        """The programs this frame runs: the shadow kernels of variant `every` ("_every": the plain
        loop, built on first use) and, while count_rays is on, the trace kernels' counting variants
        (WAVE_COUNT_RAYS: the kernels the timed frames run have no counters at all)."""
        for name in ("shadow", "shadow_finish"):
            if name + every not in self.programs:
                self.programs[name + every] = shaders.compute(self.ctx, *self.trace_sources[name + every])
        if not self.count_rays:
            return self.programs
        for name in ("closest", "shadow" + every, "shadow_finish" + every):  # the trace kernels this frame runs
            if name not in self.counting:
                source, defines = self.trace_sources[name]
                self.counting[name] = shaders.compute(self.ctx, source, {**defines, "WAVE_COUNT_RAYS": 1})
        return {name: self.counting.get(name, p) for name, p in self.programs.items()}

    def execute(self, fc) -> None:
        shape = WaveShape(self.effect, fc.sizing)
        n_pixels = shape.capacity_pixels
        common = {"ambient": tuple(fc.settings.ambient), "background": tuple(fc.settings.background),
                  "frame_seed": int(fc.settings.seed), "rt_capacity": n_pixels,
                  "wave_capacity": shape.capacity, "wave_paths_per_pixel": shape.paths_per_pixel,
                  "light_picks": fc.plan.light_picks, "wave_fetch_slots": shape.trace_kernels,
                  "shadow_probes": int(fc.settings.shadow_probes)}
        every = "" if shape.adaptive(int(fc.settings.shadow_probes)) else "_every"  # the shadow kernels' variant
        programs = self.running = self.frame_programs(every)
        users = [(a.rule, a.params) for a in fc.gpu_scene.assignments if a.effect == self.effect.name]
        # its frame-scoped parameters (uniform param_<name>)
        common.update({f"param_{k}": v for k, v in self.effect.frame_values(users).items()})
        for p in programs.values():
            set_eye_uniforms(p, fc)
            write_uniforms(p, fc, common)
        fc.gbuffer.bind_for_reading()
        fc.gpu_scene.bind()
        fc.gpu_scene.textures.use(UNIT["base_color_textures"])
        fc.accel.gpu.bind(DEFAULT_BINDING)
        bind_lists(fc)
        for part, (name, _) in self.buffers.items():
            fc.resource(name).bind_to_storage_buffer(SSBO[f"wave_{part}"])  # (wave_rays: the counting kernels add to it)
        fc.resource("hdr").bind_to_image(IMAGE["hdr"], read=False, write=True)
        self.bind_extra(fc)
        if self.persistent:
            fc.resource(self.fetch_buffer[0]).bind_to_storage_buffer(SSBO["wave_fetch"])
        wave_args = fc.resource(self.buffers["args"][0])
        if self.effect.uses_quadtree:
            fc.resource("quadtree").bind_to_storage_buffer(SSBO["quadtree_nodes"])
            set_tree_uniforms(programs["closest"], fc.gbuffer.size, fc.gbuffer.layers)
            bind_second_layer(fc)
        # Between its own kernels the pass hands on buffers and dispatch sizes only (storage, command
        # bits); the passes after it read its image through the graph's barrier at the pass's end.
        barrier = fc.gl.ctx.memory_barrier
        within = moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.COMMAND_BARRIER_BIT
        fetch_slot = iter(())  # the next trace kernel's ray counter (persistent threads), per batch

        def order(name, items):  # the sorted (key, ray) pairs the trace kernel `name` reads
            pairs, alt, table = (fc.resource(n) for n, _ in self.order_buffers.values())
            rays = ORDER_PATHS if name == "closest" else ORDER_SHADOWS
            capacity = shape.capacity if items else shape.batch

            def go():
                self.ray_order.keys(self.ray_order.programs[rays], fc.sizing.scene.vertices, pairs, capacity,
                                    wave_items=items)
                self.ray_order.sort(pairs, alt, table, capacity, wave_args, items)
                self.bind_extra(fc)  # the sort binds the photon passes' slots (rt_photon reads the map there)
            fc.stage("order", go)

        def run(name, items=1, **uniforms):
            p = programs[name]
            tracing = name in TRACE_KERNELS
            if tracing and self.persistent:
                uniforms["wave_fetch_slot"] = next(fetch_slot)
            for k, v in uniforms.items():
                if shaders.declares(p, k):
                    p[k].value = v
            if tracing and self.ray_order is not None:
                order(name, items)

            def go():
                fc.accel.layout(self.layouts.get(name, "bvh2")).bind(DEFAULT_BINDING)
                if name == "prep":
                    p.run(1, 1, 1)
                elif tracing and self.persistent:
                    p.run(persistent_groups(shape.capacity if items else shape.batch))
                else:
                    p.run_indirect(wave_args, offset=16 * items)
                barrier(within)
            fc.stage(name, go)

        one_path, bounces, chunks, hit_chunks = shape.paths_per_pixel == 1, shape.bounces, shape.chunks, shape.hit_chunks
        for base in range(0, n_pixels, shape.batch):
            for p in programs.values():
                if shaders.declares(p, "wave_batch_base"):
                    p["wave_batch_base"].value = base
            run("prep")
            fetch_slot = iter(range(shape.trace_kernels))
            for ci, (first, count) in enumerate(chunks):
                last = ci == len(chunks) - 1
                run("pixel", 0, wave_slot_first=first, wave_slot_count=count, wave_slot_stride=shape.batch)
                fuse = last and bounces == 0 and one_path
                run(("shadow_finish" if fuse else "shadow") + every, 0, wave_items=0, wave_slot_first=first,
                    wave_slot_count=count, wave_slot_stride=shape.batch)
            for b in range(bounces):
                run("closest", 1)
                for ci, (first, count) in enumerate(hit_chunks):
                    last = ci == len(hit_chunks) - 1
                    run("hit", 1, wave_bounce=b, wave_last_chunk=int(last), wave_slot_first=first,
                        wave_slot_count=count, wave_slot_stride=shape.capacity)
                    fuse = last and b == bounces - 1 and one_path
                    run(("shadow_finish" if fuse else "shadow") + every, 1, wave_items=1,
                        wave_slot_stride=shape.capacity)
            if not one_path:
                run("finish", 0)
        barrier(moderngl.ALL_BARRIER_BITS)

    def bind_extra(self, fc) -> None:
        """What a subclass binds beyond the wavefront's buffers (frame/effects/photon/shade.py: the photon
        map) to the programs this frame runs (self.running)."""

    def release(self) -> None:
        for p in [*self.programs.values(), *self.counting.values()]:
            p.release()
        if self.ray_order is not None:
            self.ray_order.release()


def count_rays(renderer, rig) -> dict:
    """Rays each traced effect's pass traces in one frame of `rig` (both eyes, every round), counted on
    the GPU: {effect: {"closest": reflection/path rays, "shadow": shadow rays, "pixels": its pixels
    (the pixel list's entries of the frame's last round)}}. One frame more than the caller's, by the
    trace kernels' counting variants (an atomic add per invocation: timed frames run kernels without).
    The counters are zeroed and read back through GPU copies: the CPU never touches a buffer the
    kernels write (the NVIDIA driver may then keep it in host memory)."""
    import numpy as np

    plan = renderer.plan(camera=rig.camera)
    passes = [p for p in renderer.compiled(plan).passes if isinstance(p, TraceEffectPass)]
    ctx = renderer.gl.ctx
    renderer.render(rig)  # the frame's resources, made or kept
    zero = ctx.buffer(bytes(RAYS_BYTES))
    base = RAYS_BYTES * len(passes)  # the readback: each pass's counters, then the lists' dispatch args
    readback = ctx.buffer(reserve=base + LIST_ARGS_BYTES * list_slots())
    try:
        for p in passes:
            p.count_rays = True
            ctx.copy_buffer(renderer.resource(p.buffers["rays"][0]), zero)
        renderer.render(rig)
        for i, p in enumerate(passes):
            ctx.copy_buffer(readback, renderer.resource(p.buffers["rays"][0]), write_offset=RAYS_BYTES * i)
        ctx.copy_buffer(readback, renderer.resource("rt_list_args"), size=LIST_ARGS_BYTES * list_slots(),
                        write_offset=base)
        words = np.frombuffer(readback.read(), np.uint32)
        out = {}
        for i, p in enumerate(passes):
            closest, shadow = (int(x) for x in words[2 * i:2 * i + 2])
            out[p.effect.name] = {"closest": closest, "shadow": shadow,
                                  "pixels": int(words[(base + LIST_ARGS_BYTES * p.slot) // 4 + 3])}
        return out
    finally:
        for p in passes:
            p.count_rays = False
        zero.release()
        readback.release()
