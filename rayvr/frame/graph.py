"""The frame graph: passes declare typed resources they read and write and why they are needed;
the graph keeps the passes the frame's output depends on, orders them by their data edges,
allocates their resources, and times each pass with a GL timer query.

A pass (rayvr/frame/passes/, one per file) subclasses `Pass` (Falcor's reflect/execute, smaller):
    name            unique; also the key of its GPU time in `Frame.timings`
    why(plan)       None when this plan cannot use it, else the reason it may run ("primary
                    visibility = raster"); the graph adds who reads what it writes
    io(plan)        its accesses: read(name), write(name, type) or compose(name), where type is
                    Texture(format, scale), Buffer(bytes rule), GBufferChannels(...) or External
    setup(gl, plan) build programs once per compiled plan
    execute(fc)     record the GL work for one frame (fc: FrameContext; fc.resource(name));
                    a pass of several kernels runs each through fc.stage(kernel, fn), so that
                    `profile=True` frames time each kernel (the benchmarks' per-kernel figures)

Edges come from the data alone. A resource has one writer, which makes the whole of it, and any
number of composers, which each overwrite their own part of it (the traced effects write their
pixels of `hdr` over what `shade` wrote); a composer runs after the writer, a reader after the
writer and every composer. Passes nothing depends on are dropped: a scene that is all `raster`
builds no BVH and dispatches no ray because no pass that reads `bvh` is left.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, fields, replace
from typing import Callable

import moderngl
import numpy as np

from ..render_options.primary_rays import MAX_SLOTS
from ..render_options.traversal import DEFAULT_TRAVERSAL
from .cameras import DEFAULT_CAMERA_MODEL
from ..gl.gpu_layout import BLOCK_TILES, CHANNELS, TILE_ENTRIES, TILE_PIXELS
from ..gl.glsl_constants import declare
from ..gl.timing import TimerQuery, valid_elapsed_ns




@dataclass(frozen=True)
class FramePlan:
    """What this frame must produce and from what; frozen, so it keys the compiled graphs."""

    effects: frozenset  # effect names the scene's materials use
    view: str = "color"  # "color" or a debug view (gpu_layout.DEBUG_VIEWS)
    eyes: int = 2  # the views the frame renders (2: a stereo pair; 1 under warp's central view)
    layer_mode: str = "vertex"  # how the G-buffer reaches its layers: vertex | geometry | multiview | passes
    primary: str = "raster"  # primary visibility: "raster" (visibility pass) or "rays" (BVH)
    camera: str = DEFAULT_CAMERA_MODEL  # camera model (rayvr/frame/cameras/), its name
    subsamples: int = 1  # sub-rays per camera sample: MSAA/SSAA (frame/cameras/sampling.py SAMPLE_COUNTS)
    shading: str = "msaa"  # with subsamples > 1: "msaa" shades once per distinct triangle, "ssaa" every sub-ray
    channels: int = 1  # colour channel sets of the camera model (cast and shaded one after another)
    reconstruct: bool = False  # the camera's samples are sparse: filled in for display (foveated)
    stereo: str = "dual"  # how the second eye is made: "dual" renders both fully
    depth_layers: int = 1  # depth layers the screen-space tracers see (2: frame/passes/second_layer.py)
    second_layer: str = "rays"  # how the second depth layer is made: "rays" (BVH) | "peel" (raster)
    dof: bool = False  # thin-lens depth of field through the quadtree (frame/passes/dof.py)
    output: str = "ldr"
    accumulate: bool = False  # running mean of samples while still (frame/passes/accumulate.py)
    denoise: tuple = ()  # effects whose pixels the edge-aware à-trous filters (frame/passes/denoise.py)
    traversal: tuple = DEFAULT_TRAVERSAL  # BVH layout per ray kind (accel/gpu.py RAY_KINDS)
    bvh_build: str = "sah"  # how the BVH is built: "sah" | "sbvh" (spatial splits; accel/sbvh.py)
    tile_culling: bool = False  # primary rays traced from tile frustum entry lists (frame/passes/primary_rays.py)
    tile_lists: int = 0  # with tile culling: the bound of each tile's triangle list, 0 none (primary_rays.py)
    block_culling: bool = False  # with tile culling: tiles cut the BVH from their block's entries (primary_rays.py)
    # with tile culling: a tile's pixels (w, h), the entries a cut lists at most, a block's tiles a side
    tile_pixels: tuple = TILE_PIXELS
    tile_entries: int = TILE_ENTRIES
    block_tiles: int = BLOCK_TILES[0]
    share_channels: bool = False  # the colour channel sets cast together, shaded once a distinct triangle (primary_rays.py)
    shading_slots: int = MAX_SLOTS  # MSAA: the most entries a pixel shades, its most covered (primary_rays.py)
    shading_merge: str = "triangle"  # MSAA: an entry is a triangle or a smooth surface (SHADING_MERGES)
    light_picks: int = 0  # lights the traced effects draw per surface by power, 0 every light (scene/light_selection.py)
    ray_order: str = "none"  # the wavefront's rays sorted before each trace kernel: "none" | "morton" (passes/ray_order.py)
    persistent: bool = False  # the wavefront's trace kernels as persistent threads (passes/persistent_threads.py)
    # MSAA rounds leave a pixel with nothing in their slot as it is where exact (frame/passes/primary_rays.py
    # skips_empty_slots); False shades it as background of weight 0, the reference tests compare with
    skip_empty_slots: bool = True
    # (effect, (material names, ...)) pairs, for the reasons --graph shows; not part of the key:
    # moving an effect to other materials compiles nothing new.
    users: tuple = field(default=(), compare=False)
    # (field, value) pairs of plan options from outside rayvr (a plugin's plan_field: FramePlan.part)
    extra: tuple = ()

    @property
    def sampled(self) -> bool:
        """The frame's colour is made of several rounds of samples, or of sparse samples: it is
        accumulated (frame/passes/sample_accumulate.py) and resolved for display (sample_resolve.py)."""
        return self.subsamples > 1 or self.channels > 1 or self.reconstruct

    @property
    def layers(self) -> int:
        """The old name of `eyes` (the G-buffer's array layers are the eyes)."""
        return self.eyes

    @property
    def samples(self) -> int:
        """The old name of `subsamples` (a pixel's samples are `spp`, its sub-rays these)."""
        return self.subsamples

    def part(self, name: str, default=None):
        """A plan field by name: rayvr's own, or a plugin's from `extra`."""
        if name in {f.name for f in fields(self)} - {"extra"}:
            return getattr(self, name)
        return dict(self.extra).get(name, default)

    def materials_using(self, effect: str) -> tuple:
        return next((names for e, names in self.users if e == effect), ())


# ------------------------------------------------------------------------- resource types

# GLSL image format -> (components, moderngl dtype, bytes per texel)
TEXTURE_FORMATS = {"rgba8": (4, "f1", 4), "rgba16f": (4, "f2", 8), "rgba32f": (4, "f4", 16),
                   "r32f": (1, "f4", 4), "rg32f": (2, "f4", 8), "r32ui": (1, "u4", 4), "rg32ui": (2, "u4", 8),
                   "rgba32ui": (4, "u4", 16)}


@dataclass(frozen=True)
class Sizing:
    """What resource sizes follow from: the eye image size, the layers, the scene and device."""

    size: tuple
    layers: int
    scene: object = None
    assignments: tuple = ()
    max_ssbo_bytes: int = 0
    depth_layers: int = 1  # FramePlan.depth_layers
    wave_buffer_bytes: int | None = None  # largest wavefront buffer (None: frame/passes/trace_effect.py WAVE_BUFFER_BYTES)
    light_picks: int = 0  # FramePlan.light_picks (the wavefront's shadow slots per surface)

    @property
    def pixels(self) -> int:
        return self.size[0] * self.size[1] * self.layers


@dataclass(frozen=True)
class Texture:
    """A layered 2D texture (one layer per eye) of `format`, eye pixels / 2**scale; `layers`
    fixes the layer count (the two warped eyes of a frame that renders one central view)."""

    format: str
    scale: int = 0
    layers: int = 0  # 0: one per rendered eye (Sizing.layers)

    def __post_init__(self):
        if self.format not in TEXTURE_FORMATS:
            raise ValueError(f"unknown texture format {self.format!r}; allowed: {', '.join(TEXTURE_FORMATS)}")

    def extent(self, s: Sizing) -> tuple:
        return max(1, s.size[0] >> self.scale), max(1, s.size[1] >> self.scale), self.layers or s.layers

    def nbytes(self, s: Sizing) -> int:
        w, h, n = self.extent(s)
        return w * h * n * TEXTURE_FORMATS[self.format][2]

    def describe(self, s: Sizing) -> str:
        w, h, n = self.extent(s)
        scale = f" (eye pixels / {1 << self.scale})" if self.scale else ""
        return f"texture {self.format} {w}x{h}x{n}{scale}"


@dataclass(frozen=True)
class Buffer:
    """A storage buffer whose size follows from the frame by `bytes_for` (`rule` says how)."""

    bytes_for: Callable = field(compare=False)
    rule: str = ""
    zeroed: bool = False  # allocated as zeros (the pass keeps it so between frames)
    max_extent: int = 0  # largest eye width/height its contents can address (0: any)

    def nbytes(self, s: Sizing) -> int:
        return max(int(self.bytes_for(s)), 4)

    def describe(self, s: Sizing) -> str:
        return f"buffer {self.rule}"


@dataclass(frozen=True)
class GBufferChannels:
    """Channels of the layered G-buffer (rayvr/frame/gbuffer.py); all live in one GBuffer per size."""

    channels: tuple

    def nbytes(self, s: Sizing) -> int:
        per = {"depth": 4, **{k: v[2] for k, v in TEXTURE_FORMATS.items()}}
        fmt = {c.name: (c.glsl_format or "depth") for c in CHANNELS}
        return sum(per[fmt[c]] for c in self.channels) * s.pixels

    def describe(self, s: Sizing) -> str:
        fmt = {c.name: (c.glsl_format or "depth32f") for c in CHANNELS}
        chans = ", ".join(f"{c} {fmt[c]}" for c in self.channels)
        return f"G-buffer {s.size[0]}x{s.size[1]}x{s.layers}: {chans}"


@dataclass(frozen=True)
class External:
    """Owned outside the frame (the scene's BVH): the graph orders by it, allocates nothing."""

    what: str

    def nbytes(self, s: Sizing) -> int:
        return 0

    def describe(self, s: Sizing) -> str:
        return self.what


@dataclass(frozen=True)
class Access:
    resource: str
    mode: str  # "read", "write" (makes all of it) or "compose" (overwrites a part, after the writer)
    type: object = None  # the resource's type, on a write


def read(name: str) -> Access:
    return Access(name, "read")


def write(name: str, type_) -> Access:
    return Access(name, "write", type_)


def compose(name: str) -> Access:
    return Access(name, "compose")


# ----------------------------------------------------------------------------------- passes

class Pass:
    name = "pass"
    timed_kernels = False  # True: execute() runs its kernels through fc.stage() (profiled one by one)

    def why(self, plan: FramePlan) -> str | None:
        return ""

    def io(self, plan: FramePlan) -> list:
        return []

    def setup(self, gl, plan: FramePlan) -> None:
        pass

    def execute(self, fc) -> None:
        raise NotImplementedError

    def release(self) -> None:
        pass


class GraphError(RuntimeError):
    pass


@dataclass
class CompiledGraph:
    plan: FramePlan
    passes: list  # in execution order
    types: dict  # resource -> type
    io: dict  # pass name -> its accesses
    reasons: dict  # pass name -> why it runs

    @property
    def pass_names(self) -> list:
        return [p.name for p in self.passes]

    @property
    def rounds(self) -> set:
        """Names of the passes a sampled frame runs once per round: `sample_accumulate` and every
        pass it depends on (empty when the graph accumulates nothing)."""
        if "sample_accumulate" not in self.pass_names:
            return set()
        writers = {}
        for p in self.passes:
            for a in self.io[p.name]:
                if a.mode in ("write", "compose"):
                    writers.setdefault(a.resource, []).append(p.name)
        out, stack = set(), ["sample_accumulate"]
        while stack:
            name = stack.pop()
            if name not in out:
                out.add(name)
                stack += [w for a in self.io[name] if a.mode in ("read", "compose") for w in writers.get(a.resource, [])]
        return out

    def describe(self, sizing: Sizing) -> str:
        """The graph as text: passes in order with why they run, then the resources."""
        plan = self.plan
        uses = "; ".join(f"{e} ({', '.join(n)})" for e, n in plan.users) or ", ".join(sorted(plan.effects))
        lines = [f"plan: view {plan.view}, primary {plan.primary}, camera {plan.camera}, stereo {plan.stereo}, "
                 f"{plan.eyes} eye(s) ({plan.layer_mode})", f"effects: {uses}", "", "passes, in order:"]
        for i, p in enumerate(self.passes, 1):
            acc = self.io[p.name]
            fmt = lambda mode: ", ".join(a.resource for a in acc if a.mode == mode) or "-"  # noqa: E731
            lines.append(f"  {i:2d}. {p.name:16s} {self.reasons[p.name]}")
            lines.append(f"      reads {fmt('read')}; writes {fmt('write')}" +
                         (f"; composes {fmt('compose')}" if any(a.mode == "compose" for a in acc) else ""))
        lines += ["", f"resources at {sizing.size[0]}x{sizing.size[1]} x {sizing.layers} layer(s):"]
        total, channels = 0, set()
        for name, t in self.types.items():
            if isinstance(t, GBufferChannels):  # channels shared by two resources count once
                t = GBufferChannels(tuple(c for c in t.channels if c not in channels))
                channels.update(t.channels)
            nbytes = t.nbytes(sizing)
            total += nbytes
            size = f"{nbytes / 2**20:8.2f} MiB" if nbytes else "       -    "
            lines.append(f"  {name:28s} {size}  {t.describe(sizing)}")
        lines.append(f"  {'total':28s} {total / 2**20:8.2f} MiB")
        return "\n".join(lines)

    def dot(self) -> str:
        """Graphviz DOT: passes as boxes, resources as ellipses, accesses as edges."""
        out = ["digraph rayvr_frame {", "  rankdir=LR;", "  node [fontname=Helvetica];"]
        for p in self.passes:
            out.append(f'  "{p.name}" [shape=box, style=filled, fillcolor="#dde8ff", '
                       f'tooltip="{self.reasons[p.name]}"];')
        for name in self.types:
            out.append(f'  "res:{name}" [label="{name}", shape=ellipse];')
        for p in self.passes:
            for a in self.io[p.name]:
                if a.mode == "read":
                    out.append(f'  "res:{a.resource}" -> "{p.name}";')
                else:
                    style = ' [style=dashed, label="compose"]' if a.mode == "compose" else ""
                    out.append(f'  "{p.name}" -> "res:{a.resource}"{style};')
        out.append("}")
        return "\n".join(out) + "\n"


def compile_graph(candidates: list, plan: FramePlan) -> CompiledGraph:
    """The passes `plan.output` depends on, in dependency order (ties: candidate order)."""
    avail = [(p, w) for p in candidates if (w := p.why(plan)) is not None]
    io = {p.name: list(p.io(plan)) for p, _ in avail}
    if len(io) != len(avail):
        raise GraphError("two candidate passes share a name")
    writer, composers, types = {}, {}, {}
    for p, _ in avail:
        for a in io[p.name]:
            if a.mode == "write":
                if a.resource in writer:
                    raise GraphError(f"{a.resource!r} is written by both {writer[a.resource].name!r} and {p.name!r}")
                writer[a.resource], types[a.resource] = p, a.type
            elif a.mode == "compose":
                composers.setdefault(a.resource, []).append(p)

    def producers(resource: str, reader: str) -> list:
        if resource not in writer:
            raise GraphError(f"no pass produces {resource!r} (read by {reader})")
        return [writer[resource]] + composers.get(resource, [])

    def deps(p) -> list:
        out = []
        for a in io[p.name]:
            if a.mode == "read":
                out += producers(a.resource, p.name)
            elif a.mode == "compose":
                out += producers(a.resource, p.name)[:1]
        return [d for d in out if d is not p]

    needed, stack = set(), producers(plan.output, "the frame's output")
    while stack:
        p = stack.pop()
        if p.name not in needed:
            needed.add(p.name)
            stack += deps(p)
    order, done, visiting = [], set(), set()

    def visit(p) -> None:
        if p.name in done:
            return
        if p.name in visiting:
            raise GraphError(f"cycle in the frame graph at pass {p.name!r}")
        visiting.add(p.name)
        for d in deps(p):
            visit(d)
        visiting.discard(p.name)
        done.add(p.name)
        order.append(p)

    for p, _ in avail:
        if p.name in needed:
            visit(p)
    reasons = {}
    for p, why in avail:
        if p.name not in needed:
            continue
        readers = [q.name for q in order if p in deps(q)]
        fed = f"feeds {', '.join(readers)}" if readers else "makes the frame's output"
        reasons[p.name] = f"{why}; {fed}" if why else fed
    used = {a.resource for p in order for a in io[p.name]}
    return CompiledGraph(plan, order, {r: t for r, t in types.items() if r in used},
                         {p.name: io[p.name] for p in order}, reasons)


# ------------------------------------------------------------------------------ device limits

# Drivers size a resource with signed 32-bit byte counts: llvmpipe rendered a 2x8192x8192 frame
# all black (exit 0) because its position channel is exactly 2 GiB.
RESOURCE_BYTES_LIMIT = (1 << 31) - 1
MEMORY_SHARE = 0.8  # of the device's memory a frame's resources may take


class FrameTooLarge(ValueError):
    """The frame's resources do not fit the device; the message says which and what would."""


@dataclass(frozen=True)
class DeviceLimits:
    max_texture_size: int = 0
    max_ssbo_bytes: int = 0
    memory_bytes: int | None = None

    @classmethod
    def of(cls, gl) -> "DeviceLimits":
        return cls(gl.max_texture_size, gl.max_ssbo_bytes, gl.memory_bytes)


def _gib(n: int) -> str:
    return f"{n / 2**30:.2f} GiB" if n >= 2**30 else f"{n / 2**20:.1f} MiB"


def limit_problems(graph: CompiledGraph, sizing: Sizing, limits: DeviceLimits) -> list:
    """What in `graph` at `sizing` exceeds the device, one phrase each (empty: it fits)."""
    out, total = [], 0
    w, h = sizing.size
    channel_bytes = {c.name: GBufferChannels((c.name,)).nbytes(sizing) for c in CHANNELS}
    for name, t in graph.types.items():
        if isinstance(t, GBufferChannels):
            parts = {f"G-buffer channel {c}": channel_bytes[c] for c in t.channels}
        else:
            parts = {name: t.nbytes(sizing)}
        for what, n in parts.items():
            if n > RESOURCE_BYTES_LIMIT:
                out.append(f"{what} needs {_gib(n)} (a resource may hold at most 2 GiB)")
        if isinstance(t, Buffer) and limits.max_ssbo_bytes and parts[name] > limits.max_ssbo_bytes:
            out.append(f"{name} needs {_gib(parts[name])}, more than a storage buffer may hold here "
                       f"({_gib(limits.max_ssbo_bytes)})")
        if isinstance(t, Buffer) and t.max_extent and max(w, h) > t.max_extent:
            out.append(f"{name} addresses at most {t.max_extent} pixels a side")
        if isinstance(t, (Texture, GBufferChannels)) and limits.max_texture_size and \
                max(w, h) > limits.max_texture_size:
            out.append(f"{name}: textures may be at most {limits.max_texture_size} pixels a side here")
        total += t.nbytes(sizing)
    if limits.memory_bytes and total > MEMORY_SHARE * limits.memory_bytes:
        out.append(f"the frame needs {_gib(total)} of {_gib(limits.memory_bytes)} device memory")
    return list(dict.fromkeys(out))


def check_fits(graph: CompiledGraph, sizing: Sizing, limits: DeviceLimits) -> None:
    """Raise FrameTooLarge naming what does not fit and the largest eye size of this aspect that does."""
    problems = limit_problems(graph, sizing, limits)
    if not problems:
        return
    w, h = sizing.size
    lo, hi = 0.0, 1.0  # the largest scale of (w, h) that fits, by bisection
    for _ in range(30):
        mid = (lo + hi) / 2
        size = (max(1, int(w * mid)), max(1, int(h * mid)))
        if limit_problems(graph, replace(sizing, size=size), limits):
            hi = mid
        else:
            lo = mid
    fits = f"{max(1, int(w * lo))}x{max(1, int(h * lo))}" if lo > 0 else "none"
    more = f" (and {len(problems) - 2} more)" if len(problems) > 2 else ""
    raise FrameTooLarge(f"a {w}x{h} eye image ({sizing.layers} layer(s)) does not fit this device: "
                        f"{'; '.join(problems[:2])}{more}; the largest size of this aspect that fits is {fits}")


# -------------------------------------------------------------------------------- execution

class FrameResources:
    """GL objects for the resources of compiled graphs, kept while their type and size stay."""

    def __init__(self, gl):
        self.gl = gl
        self._pool: dict = {}  # name -> (key, object)

    def allocate(self, graph: CompiledGraph, sizing: Sizing) -> dict:
        from .gbuffer import GBuffer

        out = {}
        for name, t in graph.types.items():
            if isinstance(t, External):
                continue
            if isinstance(t, GBufferChannels):  # every channel lives in one GBuffer
                name, key = "gbuffer", ("gbuffer", sizing.size, sizing.layers)
            else:
                key = (t, t.nbytes(sizing), sizing.size, sizing.layers)
            have = self._pool.get(name)
            if have is None or have[0] != key:
                if have is not None:
                    have[1].release()
                ctx = self.gl.ctx
                if isinstance(t, GBufferChannels):
                    obj = GBuffer(self.gl, sizing.size, sizing.layers)
                elif isinstance(t, Texture):
                    comps, dtype, _ = TEXTURE_FORMATS[t.format]
                    obj = ctx.texture_array(t.extent(sizing), comps, dtype=dtype)
                    obj.filter = (moderngl.NEAREST, moderngl.NEAREST)
                else:
                    n = t.nbytes(sizing)
                    obj = ctx.buffer(bytes(n)) if t.zeroed else ctx.buffer(reserve=n)
                have = self._pool[name] = (key, obj)
            out[name] = have[1]
        return out

    def release(self) -> None:
        for _, obj in self._pool.values():
            obj.release()
        self._pool.clear()


@dataclass
class PassTimer:
    """GL timer queries (64-bit: timing.TimerQuery), one per name and slot. Two slots alternate
    frame by frame, so a frame's times can be read after the next frame has been recorded
    (reading waits for the GPU)."""

    raw: object  # rayvr.gl.context.RawGL
    queries: dict = field(default_factory=dict)
    slot: int = 0

    def next_frame(self) -> None:
        self.slot ^= 1

    def run(self, name: str, fn) -> None:
        key = (self.slot, name)
        q = self.queries.get(key)
        if q is None:
            q = self.queries[key] = TimerQuery(self.raw)
        with q:
            fn()

    def release(self) -> None:
        for q in self.queries.values():
            q.release()
        self.queries.clear()

    def read_ms(self, names, slot: int | None = None, since: float | None = None) -> dict:
        """GPU ms per name; a query that read back garbage (timing.valid_elapsed_ns; `since`: the
        perf_counter() when the work was recorded) is left out (unavailable), never a number."""
        slot = self.slot if slot is None else slot
        out = {}
        for n in names:
            q = self.queries.get((slot, n))
            if q is None:
                continue
            ns = q.elapsed  # waits for the GPU
            wall = None if since is None else (time.perf_counter() - since) * 1e9
            if valid_elapsed_ns(ns, wall):
                out[n] = ns / 1e6
        return out


# ------------------------------------------------------------------------------ one frame

@dataclass
class EyeImage:
    name: str
    color: np.ndarray  # (H, W, 3) uint8 sRGB, rows top-down
    depth: np.ndarray | None  # (H, W) float32 linear view depth, 0 = background; None: not read back
    aux: dict = field(default_factory=dict)  # extra channels asked for (readback.AUX_CHANNELS)

    def __iter__(self):  # color, depth = frame.left
        return iter((self.color, self.depth))


@dataclass
class Frame:
    eyes: dict
    timings: dict  # pass name -> GPU ms (with profile=True: "pass.kernel" -> GPU ms)
    view: str
    passes: tuple = ()  # the passes that ran; those missing from `timings` had no valid reading

    @property
    def timings_unavailable(self) -> list:
        return [p for p in self.passes if p not in self.timings]

    @property
    def left(self) -> EyeImage:
        return self.eyes["left"]

    @property
    def right(self) -> EyeImage:
        return self.eyes["right"]

    def __getitem__(self, eye: str) -> EyeImage:
        return self.eyes[eye]


@dataclass
class Round:
    """Which part of a sampled frame (FramePlan.sampled) the passes upstream of
    `sample_accumulate` make now: FrameGraph.execute runs them once per round, per colour channel
    set, then per slot (an SSAA sub-ray, or an MSAA triangle slot); `ordinal` counts the channel
    set's rounds (`slot` = `slots` - 1 - `ordinal`). primary_rays says how many rounds a channel
    needs in its first round (`start`), or, when that number is made on the GPU, gives a function
    that answers once the GPU has it (`start_polled`): rounds are then recorded, up to the most the
    channel may need, until the answer says enough have been."""

    channel: int = 0
    slot: int = 0
    slots: int = 1  # the channel's rounds; while `known` is False, the most it may need
    first: bool = True  # the channel's first round
    index: int = 0  # rounds of this frame before this one
    active: bool = False  # the frame runs rounds (its graph accumulates samples)
    ordinal: int = 0  # rounds of this channel set before this one
    count: object = None  # start_polled's count(wait) -> the channel's rounds (None: not on the GPU yet)
    known: bool = True
    # passes/round_gate.py RoundGate: this round's frame-wide dispatch sizes, made on the GPU from the
    # count, where the round was recorded before the count was known (None: dispatch directly)
    gate: object = None
    tiles: object = None  # the round's listed tiles' dispatch buffer (round_gate.py), once its select made them

    def start(self, slots: int) -> None:
        self.slots = slots if self.active else 1
        self.slot = self.slots - 1

    def start_polled(self, count, most: int) -> None:
        """`count(wait=False)` is the channel's number of rounds, or None while the GPU has not made
        it; `count(wait=True)` waits for it. Polled after each round is recorded (finished())."""
        self.count, self.known = count, not self.active
        self.start(most)

    def finished(self) -> bool:
        """Called once this round's passes are recorded: whether the channel set has all its rounds."""
        if not self.known:
            n = self.count(False)
            if n is not None:
                self.slots, self.known = n, True
        return self.ordinal + 1 >= self.slots

    def needed(self) -> int:
        """The rounds the channel set needed (may wait for the GPU: for benchmarks and tests)."""
        return self.slots if self.known else self.count(True)

    def next(self) -> "Round":
        return Round(self.channel, self.slot - 1, self.slots, False, self.index + 1, self.active, self.ordinal + 1,
                     self.count, self.known)


# Green, cast last of three colour channel sets: the G-buffer the frame keeps (depth, aux) is the
# middle wavelength's; with shared channel shading (frame/passes/primary_rays.py shares_channels) its
# block of sub-rays comes first, so a triangle all sets hit is shaded at green's ray.
SHARED_CHANNEL = declare("SHARED_CHANNEL", 1)


def channel_order(plan: FramePlan) -> list:
    """Colour channel sets in the order a frame casts them: green (SHARED_CHANNEL) last; with shared
    channel shading one round sequence for all three, whose passes see green's set."""
    if plan.share_channels:
        return [SHARED_CHANNEL]
    return [0, 2, SHARED_CHANNEL] if plan.channels == 3 else list(range(plan.channels))


@dataclass
class FrameContext:
    """What passes see while a frame is recorded (and what readback reads afterwards)."""

    gl: object
    scene: object
    gpu_scene: object
    accel: object  # the scene's BVH (rayvr/accel/scene.py), built by the `bvh` pass when needed
    eyes: list  # the rendered eyes (G-buffer layers): the central one under stereo `warp`
    plan: FramePlan
    settings: object
    sizing: Sizing
    resources: dict = field(default_factory=dict)
    pass_names: list = field(default_factory=list)
    timer_slot: int = 0
    recorded_at: float = 0.0  # perf_counter() when its GL work began to be recorded
    profiler: PassTimer | None = None  # set: passes' kernels are timed one by one (stage names)
    stage_names: list = field(default_factory=list)
    current_pass: str = ""
    samples: object = None  # rayvr.frame.accumulation.SampleState: this frame's sample index, reset, reprojection
    out_eyes: list = field(default_factory=list)  # the eyes the frame returns (default: `eyes`)

    def __post_init__(self):
        self.out_eyes = self.out_eyes or list(self.eyes)
    round: Round = field(default_factory=Round)
    timer_keys: list = field(default_factory=list)  # (timer query key, pass name): a pass times once per round
    channel_rounds: list = field(default_factory=list)  # each colour channel set's last Round (sampled frames)
    uniform_cache: dict = field(default_factory=dict)  # values passes compute once per frame (compute.set_eye_uniforms)

    def resource(self, name: str):
        return self.resources[name]

    @property
    def gbuffer(self):
        return self.resources["gbuffer"]

    def stage(self, kernel: str, fn) -> None:
        """Run one kernel of the current pass; timed on its own when profiling."""
        if self.profiler is None:
            fn()
            return
        base = f"{self.current_pass}.{kernel}" if kernel else self.current_pass
        # A kernel run again in this frame (each batch, bounce, chunk, round) gets its own query
        # ("name#k"); read_ms sums them under the base name.
        name = base
        repeat = sum(1 for n in self.stage_names if n.split("#")[0] == base)
        if repeat:
            name += f"#{repeat}"
        self.stage_names.append(name)
        self.profiler.run(name, fn)


class FrameGraph:
    """Compiles plans once (passes from `candidates(plan)`, set up), allocates their resources
    and records frames; every pass under its own GL timer query, or with `profile` every kernel."""

    def __init__(self, gl, candidates):
        self.gl, self.candidates = gl, candidates
        self.limits = DeviceLimits.of(gl)
        self._fits: set = set()  # (plan, sizing) pairs checked against the limits
        self._compiled: dict = {}
        self.resources = FrameResources(gl)
        self.timer = PassTimer(gl.raw)
        self.kernel_timer = PassTimer(gl.raw)

    def compile(self, plan: FramePlan) -> CompiledGraph:
        graph = self._compiled.get(plan)
        if graph is None:
            graph = compile_graph(self.candidates(plan), plan)
            for p in graph.passes:
                p.setup(self.gl, plan)
            self._compiled[plan] = graph
        return graph

    def execute(self, graph: CompiledGraph, fc: FrameContext, profile: bool = False) -> None:
        key = (graph.plan, fc.sizing.size, fc.sizing.layers)
        if key not in self._fits:  # before anything is allocated: a clear error, not a black frame
            check_fits(graph, fc.sizing, self.limits)
            self._fits.add(key)
        fc.resources = self.resources.allocate(graph, fc.sizing)
        fc.pass_names = graph.pass_names
        fc.recorded_at = time.perf_counter()
        timer = self.kernel_timer if profile else self.timer
        timer.next_frame()
        fc.timer_slot = timer.slot
        fc.profiler = self.kernel_timer if profile else None
        fc.timer_keys, fc.channel_rounds = [], []

        def run(p) -> None:
            fc.current_pass = p.name
            if profile and p.timed_kernels:  # timer queries do not nest: its kernels are timed, it is not
                p.execute(fc)
            elif profile:
                fc.stage("", lambda: p.execute(fc))
            else:
                key = f"{p.name}#{fc.round.index}" if fc.round.index else p.name
                fc.timer_keys.append((key, p.name))
                timer.run(key, lambda: p.execute(fc))

        rounds = graph.rounds
        if rounds:  # a sampled frame: what sample_accumulate depends on runs once per round
            index = 0
            for ch in channel_order(graph.plan):
                fc.round = Round(ch, index=index, active=True)
                while True:
                    for p in graph.passes:
                        if p.name in rounds:
                            run(p)
                    index += 1
                    if fc.round.finished():
                        break
                    fc.round = fc.round.next()
                fc.channel_rounds.append(fc.round)
            fc.round.gate = fc.round.tiles = None  # the passes after the rounds dispatch directly
        for p in graph.passes:
            if p.name not in rounds:
                run(p)

    def read_ms(self, fc: FrameContext) -> dict:
        """GPU ms per pass (or per kernel for a profiled frame), summed over a sampled frame's
        rounds; waits for the GPU."""
        return {name: sum(ms) for name, ms in self.read_round_ms(fc).items()}

    def read_round_ms(self, fc: FrameContext) -> dict:
        """GPU ms per pass (or kernel) as a list, one entry each time it ran, in order: a sampled
        frame's passes once per round (what an MSAA round costs beside the pixels it shades)."""
        if fc.profiler is not None:
            got = self.kernel_timer.read_ms(fc.stage_names, fc.timer_slot, fc.recorded_at)
            keys = [(k, k.split("#")[0]) for k in fc.stage_names]
        else:
            keys = fc.timer_keys or [(n, n) for n in fc.pass_names]
            got = self.timer.read_ms([k for k, _ in keys], fc.timer_slot, fc.recorded_at)
        out: dict = {}
        for key, name in keys:
            if key in got:
                out.setdefault(name, []).append(got[key])
        return out

    def release(self) -> None:
        for graph in self._compiled.values():
            for p in graph.passes:
                p.release()
        self._compiled.clear()
        self.resources.release()
        self.timer.release()
        self.kernel_timer.release()
