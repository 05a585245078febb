"""`primary_rays`: the ray-traced alternative to the visibility raster (RenderSettings.primary =
"rays", and any camera model a rasterizer cannot sample, or sub-rays per sample): each sample's
camera ray through the BVH (glsl/rt/primary.comp), leaving the triangle ID, the sub-ray and the
hit distance for the G-buffer resolve.

Sampled frames (FramePlan.sampled) run in rounds (frame/graph.py FrameGraph.execute): per colour
channel set, then per sub-ray (SSAA: each round casts one sub-ray of every sample) or per slot
of the distinct triangles the sub-rays hit (MSAA: the first round of a channel casts all N
sub-rays, keeps the distinct triangles with their coverage, and counts on the GPU how many
rounds the channel needs, the most any pixel has; each round then shades one triangle per
pixel). The MSAA trace casts one sub-ray per invocation (a workgroup: a block of pixels times
their sub-rays) and merges each pixel's hits in shared memory, every sub-ray's invocation taking
part; `msaa_lists` is the numpy twin of that merge. Each round also writes every pixel's weight in
the frame's colour (`sample_weight`), which `sample_accumulate` applies.

The CPU never waits for the count (Round.start_polled): it is copied to a readback buffer behind
a fence, and after each round is recorded the fence is polled without waiting; until it answers,
another round is recorded (at most msaa_slots), so the GPU is never left idle while the CPU
waits and then records (on the GPU, room, 4x: ~1.3 ms of the frame was that). Each round's select
takes its slot from the count on the GPU: round k of a channel selects slot count - 1 - k, so
slots run from the last to 0 and the G-buffer the frame keeps (depth, aux channels) is each
pixel's most covered triangle. A round past the count (slot < 0: recorded before the count was
known) gives every pixel the weight ROUND_SKIPPED (glsl/common/round_skip.glsl) and writes no
visibility: the round's gbuffer resolve, shade, classify and sample_accumulate leave those pixels
alone, so the G-buffer stays the slot-0 round's and nothing is added; and a round recorded before
the count was known runs its frame-wide passes through the round gate (round_gate.py), which
dispatches nothing where the round lies past the count. The frame is bit-identical
however late the count is known (tests force both ends through COUNT_POLL). Empty slots above 0
(a pixel with fewer triangles than the count, most pixels in most rounds) are skipped the same
way where exact (`skips_empty_slots`, FramePlan.skip_empty_slots): instead of a background
resolved, shaded and added with weight 0, a 4-byte weight read per pass.

Tile frustum culling (FramePlan.tile_culling, RenderSettings.tile_culling, `--tile-culling`; by
default where it measured faster on the GPU, primary_rays.culls_tiles): each channel set's first
round first runs a `cull` stage (glsl/accel/tile_cull.comp with TILE_CAMERA): one workgroup per
tile of pixels (16 x 8 by default; --tile-size) bounds every ray the rounds will cast there
(all sub-rays of each sample's footprint, thin-lens lens points, this channel set's distortion) with
a conservative frustum and lists the BVH entry nodes it meets, nearest first; the trace then starts
each ray from its tile's entries instead of the root. Exact: the same triangle and distance as
per-ray traversal (tests/test_tile_culling_frame.py). The entries are child pairs of the binary
layout, so with tile culling primary rays walk `bvh2`, whatever `traversal` names for them. Tiles
whose rays spread beyond ~84 deg (wide cameras at low resolution) fall back to the root's children.

Tile triangle lists (FramePlan.tile_lists, `--tile-lists N`; HVVR's tile beams and sample testing):
after the cull a `lists` stage (glsl/accel/tile_tris.comp) lists each tile's frustum triangles
nearest first; the cast/trace then runs glsl/rt/tile_samples.comp, a workgroup a tile (or a band of
its rows, `sample_group`) and an invocation a pixel with all its sub-rays, which sets each listed
triangle up once in workgroup memory as 2D edge functions in the tile's frame and tests the pixel's
sub-rays against them, the candidates with the exact test; primary.comp (TILE_LIST_OVERFLOW) casts
the tiles whose list overflowed per ray from their entries. Exact.

Shared channel shading (FramePlan.share_channels, `share_channel_shading`, shares_channels; HVVR's
MSAA over colour channels): a chromatic camera's three colour channel sets are cast together, as
sub-rays of each sample (CHANNEL_SAMPLES 3 in glsl/common/camera.glsl: a block of the sample's
sub-rays a set, green's first), through the MSAA trace: one frame round a distinct triangle of a
pixel, as with MSAA, shaded once at the sub-ray its mask centres on, every channel taking its own
share of it (`channel_weight`, which sample_accumulate applies). The frame culls, traces and
rounds once for all three sets instead of once a set.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

import moderngl
import numpy as np

from ...gl import shaders
from ...gl.glsl_constants import declare as declare_constant
from ...accel.frustum import tile_grid
from ...accel.gpu import DEFAULT_BINDING, layout_defines
from ..effect_registry import EFFECTS
from ..graph import SHARED_CHANNEL, Buffer, FramePlan, GBufferChannels, Pass, Texture, read, write
from ...gl.gpu_layout import BLOCK_TILES, IMAGE, NO_HIT, SSBO, TILE_ENTRIES, TILE_PIXELS, channel
from .compute import camera_defines, dispatch_per_pixel, pixel_grid, set_eye_uniforms
from . import round_gate
from .round_gate import RoundGate, round_tile_bytes
from ...options import PlanRefusal, plan_part
from ...render_options.primary_rays import TILE_SIZES, TILE_ENTRY_BOUNDS, BLOCK_SIDES


def tile_pixels(text: str) -> tuple[int, int]:
    """A TILE_SIZES spelling ("16x8") as (w, h)."""
    w, h = text.split("x")
    return int(w), int(h)


# The tile list stage (glsl/accel/tile_tris.comp): invocations a tile, nodes one sweep of a tile's walk
# may hold (more: the tile overflows, as with more than its bound of triangles), and the count that says so.
DEFAULT_TILE_TRIS = declare_constant("DEFAULT_TILE_TRIS", 256)  # tile_tris.comp's bound when compiled alone (tests)
TILE_LIST_GROUP = declare_constant("TILE_LIST_GROUP", 128)
TILE_FRONT = declare_constant("TILE_FRONT", 256)
# Sweeps a beam's cut (accel/tile_cut.glsl) or a tile's list walk (accel/tile_tris.comp) makes at
# most. A tree's walk takes at most its depth (64, accel/bvh.py max_depth) plus one sweep per entry a
# cut left for room (32): the bound never binds on a valid tree and only keeps a malformed one from
# hanging the GPU (a cut stopped early still covers every triangle; a list walk overflows to per ray).
BEAM_MAX_SWEEPS = declare_constant("BEAM_MAX_SWEEPS", 128)
TILE_OVERFLOW = declare_constant("TILE_OVERFLOW", 0xFFFFFFFF, uint=True)
# The edge filter's rounding bound (glsl/rt/tile_samples.comp), relative to the edge's vertex
# distances: the exact test's and the filter's float errors are a few ulps (~1e-7) of those.
EDGE_SLACK = declare_constant("EDGE_SLACK", 1e-5)


# Shared channel shading by default up to this --msaa: faster than the sets apart at 1x, 4x and 8x (on the GPU,
# Sponza's worst pose: 6.9 / 14.4 / 23.9 ms against 11.1 / 21.1 / 38.6), slower at 16x (47.9 against
# 44.5; its 48 sub-rays a pixel trace at 1.6x the sets' apart; docs/design.md).
SHARED_AUTO_MSAA = 8


def primary_visibility(settings, camera) -> str:
    """The plan's primary visibility: `settings.primary` where a rasterizer can sample the camera
    (a planar model, one sub-ray per sample), else ray-cast."""
    return settings.primary if camera.rasterizable and settings.msaa == 1 else "rays"


# How the renderer casts primary rays where the settings leave it to it (tile_culling, tile_lists,
# block_culling None): per camera model and sub-rays per sample, the variant that measured fastest
# (the asset names its runs; `rayvr bench vr --variants` writes its successor, primary_visibility.json).
MEASURED_CHOICES = Path(__file__).resolve().parents[2] / "assets" / "primary_visibility.json"
PRIMARY_KNOBS = ("tile_culling", "tile_lists", "block_culling", "tile_size", "tile_entries", "block_tiles")
# What a knob is where neither the settings nor a measured choice say (the shapes timed before they were knobs).
KNOB_DEFAULTS = {"tile_lists": 0, "block_culling": False, "tile_size": "x".join(map(str, TILE_PIXELS)),
                 "tile_entries": TILE_ENTRIES, "block_tiles": BLOCK_TILES[0]}


def measured_choices(path: Path | None = None) -> dict:
    """{camera model: {sub-rays per sample: {knob: value}}} of the measured choices file (default
    MEASURED_CHOICES), read once."""
    return _read_choices(Path(path or MEASURED_CHOICES))


@functools.lru_cache(maxsize=None)
def _read_choices(path: Path) -> dict:
    data = json.loads(Path(path).read_text())
    out = {model: {int(n): dict(knobs) for n, knobs in counts.items()} for model, counts in data["choices"].items()}
    for model, counts in out.items():
        for n, knobs in counts.items():
            if (set(knobs) != set(PRIMARY_KNOBS) or ((knobs["tile_lists"] or knobs["block_culling"])
                                                      and not knobs["tile_culling"])
                    or knobs["tile_size"] not in TILE_SIZES or knobs["tile_entries"] not in TILE_ENTRY_BOUNDS
                    or knobs["block_tiles"] not in BLOCK_SIDES
                    or (knobs["block_culling"] and knobs["tile_entries"] > knobs["block_tiles"] ** 2)):
                raise ValueError(f"{path}: {model} at {n}x must set {', '.join(PRIMARY_KNOBS)}: tile lists "
                                 f"and block culling only with tile culling, a tile size of {', '.join(TILE_SIZES)}, "
                                 f"a tile entry bound of {', '.join(map(str, TILE_ENTRY_BOUNDS))} (with block "
                                 f"culling at most the block's tiles), a block side of "
                                 f"{', '.join(map(str, BLOCK_SIDES))}; got {knobs}")
    return out


def measured_choice(camera: str, samples: int) -> dict | None:
    """The measured choice of PRIMARY_KNOBS for a `camera` model (its name) at `samples` sub-rays per
    sample (that of the largest count measured at or below it), or None for a model never measured
    (a plugin's: CameraModel.culls_tiles_by_default decides)."""
    counts = measured_choices().get(camera, {})
    below = [n for n in counts if n <= samples]
    return counts[max(below)] if below else None


def culls_tiles(settings, camera: str = "pinhole") -> bool:
    """Whether ray-cast primaries of a `camera` model (its name) are tile-culled: tile_culling, or
    when None, the measured choice (measured_choice; on the GPU culling with block beams won for
    every model but the foveated one), for a model never measured with several sub-rays where it
    declares it (CameraModel.culls_tiles_by_default)."""
    from ..cameras import CAMERA_MODELS

    if settings.tile_culling is not None:
        return settings.tile_culling
    if settings.tile_lists or settings.block_culling or settings.block_tiles or settings.tile_size \
            or settings.tile_entries:  # the lists and the blocks feed the cull's entries; a shape asks for tiles
        return True
    choice = measured_choice(camera, settings.msaa)
    if choice is not None:
        return bool(choice["tile_culling"])
    return settings.msaa > 1 and CAMERA_MODELS[camera].culls_tiles_by_default


def knob(settings, name: str, camera: str = "pinhole"):
    """A tile-culled frame's PRIMARY_KNOBS `name` (not tile_culling: culls_tiles) for a `camera`
    model (its name): the settings' value, or when None, the measured choice, else KNOB_DEFAULTS."""
    value = getattr(settings, name)
    if value is None:
        value = (measured_choice(camera, settings.msaa) or {}).get(name, KNOB_DEFAULTS[name])
    return value


def culls_blocks(settings, camera: str = "pinhole") -> bool:
    """Whether tile-culled ray-cast primaries of a `camera` model (its name) start each tile's cut
    from its block's entries: block_culling, or when None, the measured choice (off where never timed)."""
    if settings.block_culling is None and settings.block_tiles:   # a block's shape asks for blocks
        return True
    return bool(knob(settings, "block_culling", camera))


def tile_list_bound(settings, camera: str = "pinhole") -> int:
    """The triangles a tile's list holds at most for ray-cast primaries of a `camera` model (its
    name) when they are tile-culled: tile_lists, or when None, the measured choice; 0: no lists,
    per-ray traversal from the tile's entries."""
    return int(knob(settings, "tile_lists", camera))


def tile_shape(settings, camera: str = "pinhole", blocks: bool = False) -> dict:
    """The FramePlan fields of a tile-culled frame's shapes (`blocks`: with block culling): tile_pixels,
    tile_entries and block_tiles, each the settings' or the measured choice (`knob`). An entry bound
    left to the choice is cut to a smaller block's tiles (a block's cut tests its entries one a tile);
    one asked for beyond them is refused (ValueError)."""
    entries, side = int(knob(settings, "tile_entries", camera)), int(knob(settings, "block_tiles", camera))
    if blocks and entries > side * side:
        if settings.tile_entries is not None:
            raise PlanRefusal(f"a block of {side}x{side} tiles cuts to at most {side * side} entries, one a tile, "
                              f"and {entries} were asked: use larger blocks or fewer entries",
                              "for instance", ("tile_entries", max(b for b in TILE_ENTRY_BOUNDS if b <= side * side)))
        entries = max(b for b in TILE_ENTRY_BOUNDS if b <= side * side)
    return {"tile_pixels": tile_pixels(knob(settings, "tile_size", camera)), "tile_entries": entries,
            "block_tiles": side if blocks else BLOCK_TILES[0]}


MASK_BITS = 64  # sub-rays a coverage mask holds (glsl/rt/sub_mask.glsl: at most two words)
SHARED_SETS = 3  # colour channel sets cast together with shared channel shading (glsl/common/camera.glsl)


def shares_channels(settings, camera, samples: int, effects, view: str) -> bool:
    """Whether a frame casts its three colour channel sets together as sub-rays and shades once per
    distinct triangle: a camera of three sets, MSAA (or one sub-ray) whose sub-rays for all three sets
    fit a coverage mask of two words (--msaa 16 at most: 48 sub-rays; unset, SHARED_AUTO_MSAA), the
    colour view, and no effect that reads other pixels' G-buffer in a round (the quadtree's: a
    skipped pixel's G-buffer is an earlier round's)."""
    share = settings.share_channel_shading
    if share is None:
        share = samples <= SHARED_AUTO_MSAA
    return (share and camera.channels == SHARED_SETS and not settings.ssaa
            and samples * SHARED_SETS <= MASK_BITS and view == "color"
            and not any(EFFECTS[e].uses_quadtree for e in effects if e in EFFECTS))


@plan_part("primary", after=("sampling",))
def primary_plan(ask, plan) -> None:
    """Primary visibility, the tile and block culling of ray-cast primaries with their shapes, shared
    channel shading, and the MSAA merge's slots (shading_slots, shading_merge: as given)."""
    st, camera = ask.settings, ask.camera
    primary = primary_visibility(st, camera)
    culled = primary == "rays" and culls_tiles(st, camera.name)
    if primary == "rays" and not culled:
        for option, what in (("tile_lists", "tile triangle lists start from the tile culling's entry lists"),
                             ("block_culling", "block culling hands its entries to the tile culling")):
            if getattr(st, option):
                raise PlanRefusal(what, "leave out", ("tile_culling", False))
    blocks = culled and culls_blocks(st, camera.name)
    shape = tile_shape(st, camera.name, blocks) if culled else \
        {"tile_pixels": TILE_PIXELS, "tile_entries": TILE_ENTRIES, "block_tiles": BLOCK_TILES[0]}
    plan.update(primary=primary, tile_culling=culled, tile_lists=tile_list_bound(st, camera.name) if culled else 0,
                block_culling=blocks, **shape,
                share_channels=primary == "rays" and shares_channels(st, camera, plan["subsamples"], ask.effects, ask.view))


# tile_samples.comp's workgroup memory: each pixel's sub-rays' hits (8 bytes a sub-ray) and the load of
# triangles (56 bytes each, one an invocation), kept under 24 KiB of the 32 KiB the smallest GL 4.3
# driver measured here gives (llvmpipe; NVIDIA: 48 KiB)
SAMPLE_SHARED_BYTES = 24 * 1024


def sample_group(rays: int, tile: tuple[int, int] = TILE_PIXELS) -> int:
    """Pixels of a tile_samples.comp workgroup whose pixels cast `rays` sub-rays each: the whole
    `tile` (w, h), or the largest band of its rows (a power of two) whose state fits SAMPLE_SHARED_BYTES."""
    group = tile[0] * tile[1]
    while group > tile[0] and group * (8 * rays + 56) > SAMPLE_SHARED_BYTES:
        group //= 2
    return group


# Sub-rays on one smooth surface are linked where their distances agree to this share of the
# larger (an entry chains them: a surface seen at a slant spreads its sub-rays' distances by more):
# the chromatic camera's 12 sub-rays on the room's sphere 0.65 m away at 96x64 pixels span 4 % in
# steps up to 1.2 %; a torus's front and its own far side behind it differ by 10 % and more.
SURFACE_DEPTH_TOLERANCE = declare_constant("SURFACE_DEPTH_TOLERANCE", 0.03)
# invocations of an MSAA trace workgroup a colour channel set: a block of 64 / N pixels, N sub-rays each
MSAA_GROUP = 64
SAMPLE_WEIGHT = Texture("r32f")
CHANNEL_WEIGHT = Texture("rgba32f")  # shared channel shading: each channel's weight of the round's surface
# How recording learns an MSAA channel's count of rounds: "fence" polls it after each round without
# waiting; "wait" reads it after the first round, waiting for the GPU; "never" does not read it
# (every channel then records msaa_slots rounds). Frames are identical under all three (tests).
# A test hook, not a setting: read afresh by each frame (no program or resource depends on it),
# set only through tests/conftest.py's `count_poll` fixture.
COUNT_POLLS = ("fence", "wait", "never")
COUNT_POLL = "fence"


def msaa_block(samples: int) -> tuple[int, int]:
    """Pixels (w, h) of an MSAA trace workgroup: the largest power of two of them whose `samples`
    sub-rays (one colour channel set's) fit MSAA_GROUP invocations, as square as it allows; a
    workgroup is the block's sub-rays of every set it casts (shared channel shading: 3 sets, 192
    invocations, full warps: 48 sub-rays a 1-pixel group at 16x left a quarter of the lanes idle,
    the trace 2x the three sets cast apart on Sponza). A
    power of two on both sides, so a block lies in one tile (TILE_SIZES: powers of two, at least 8
    a side): with tile lists the trace casts only the tiles whose list overflowed, and leaves the
    group as a whole (a group over two tiles would leave some invocations before the barriers the
    others reach: undefined, and wrong on the NVIDIA GPU with the 3 sub-rays of shared channel shading at
    1x, where 64 // 3 = 21 pixels made 4x5 blocks)."""
    pixels = 1 << (max(1, MSAA_GROUP // samples).bit_length() - 1)
    w = 1 << (pixels.bit_length() // 2)
    return w, pixels // w


def msaa_coverage(mask: int, n_sub: int, channel_blocks: int = 1) -> int:
    """The covered count of a kept entry's coverage mask (glsl/rt/primary_out.glsl msaa_coverage): its
    sub-rays, or with shared channel shading (channel_blocks 3: n_sub / 3 sub-rays a colour channel
    set, green's block first) each set's, 5 bits a set (channel c at bit 5c)."""
    if channel_blocks == 1:
        return bin(mask).count("1")
    per = n_sub // channel_blocks
    return sum(bin(mask >> (b * per) & ((1 << per) - 1)).count("1") << (5 * ((b + SHARED_CHANNEL) % 3))
               for b in range(channel_blocks))


def msaa_lists(tris: np.ndarray, ts: np.ndarray, offsets: np.ndarray, slots: int,
               sampled: np.ndarray | None = None, channel_blocks: int = 1,
               surfaces: np.ndarray | None = None) -> np.ndarray:
    """Numpy twin of primary.comp's MSAA merge: per pixel, from its N sub-rays' triangles `tris`
    (..., N) (NO_HIT: background) and distances `ts`, the list msaa_hits holds, (slots, ..., 4)
    uint32 entries (triangle, coverage (msaa_coverage of its mask), representative sub-ray | count
    << 8 | covered << 16 (entry 0 only; msaa_coverage, summed), distance bits), most covered first,
    ties in order of first sub-ray, the `slots` most covered kept (the others' sub-rays dropped); unused
    entries zero here (the GPU leaves entries past a pixel's count as the buffer held them: only
    the first count are defined, and only those are read). An entry is the sub-rays on one triangle,
    or with `surfaces` (each triangle's smooth surface, scene/surfaces.py: shading_merge "surface")
    the sub-rays linked through others on one surface whose distances agree within
    SURFACE_DEPTH_TOLERANCE (glsl/rt/same_surface.glsl). An entry's triangle is its representative's. `offsets` (N, 2): the sub-rays' footprint offsets (cameras/sampling.subsamples);
    the representative is the sub-ray nearest the mean offset of its mask (the first of equally
    near ones). `sampled` (...): False where the pixel has no sample (an empty list).
    `channel_blocks` 3: the sub-rays are shared channel shading's, a block of N / 3 a colour set."""
    tris = np.asarray(tris, np.uint32)
    shape, n_sub = tris.shape[:-1], tris.shape[-1]
    flat_t, flat_d = tris.reshape(-1, n_sub), np.asarray(ts, np.float32).reshape(-1, n_sub)
    ok = np.ones(len(flat_t), bool) if sampled is None else np.asarray(sampled, bool).reshape(-1)
    out = np.zeros((slots, len(flat_t), 4), np.uint32)
    out[0, :, 0] = NO_HIT
    tolerance = np.float32(SURFACE_DEPTH_TOLERANCE)

    def linked(a, b, px):
        ta, tb = flat_t[px, a], flat_t[px, b]
        if ta == tb:
            return True
        if surfaces is None or ta == NO_HIT or tb == NO_HIT or surfaces[ta] != surfaces[tb]:
            return False
        da, db = flat_d[px, a], flat_d[px, b]
        return abs(da - db) <= tolerance * max(da, db)

    for px in np.flatnonzero(ok):
        masks, placed = [], 0
        for first in range(n_sub):  # entries in order of their first sub-ray: the linked sub-rays' components
            if placed >> first & 1:
                continue
            entry, frontier = {first}, [first]
            while frontier:
                m = frontier.pop()
                for o in range(first + 1, n_sub):
                    if o not in entry and linked(m, o, px):
                        entry.add(o)
                        frontier.append(o)
            masks.append(sum(1 << i for i in entry))
            placed |= masks[-1]
        pop = [bin(m).count("1") for m in masks]
        order = sorted(range(len(masks)), key=lambda k: (-pop[k], k))[:slots]  # the most covered are kept
        masks = [masks[k] for k in order]
        coverage = [msaa_coverage(m, n_sub, channel_blocks) for m in masks]
        for rank, mask in enumerate(masks):
            bits = [i for i in range(n_sub) if mask >> i & 1]
            dist = ((offsets[bits] - offsets[bits].mean(0)) ** 2).sum(1)
            best = bits[int(np.argmin(dist))]
            meta = best | ((len(masks) << 8) | (sum(coverage) << 16) if rank == 0 else 0)
            out[rank, px] = (flat_t[px, best], coverage[rank], meta, flat_d[px, best].view(np.uint32))
    return out.reshape((slots,) + shape + (4,))


def frame_tiles(sizing, tile: tuple[int, int] = TILE_PIXELS) -> int:
    """Tiles of a frame (tile culling): `tile` (w, h) pixel blocks of every layer."""
    nx, ny = tile_grid(*sizing.size, tile)
    return nx * ny * sizing.layers


def tile_defines(plan: FramePlan) -> dict:
    """The shaders' defines of a tile-culled plan's shapes and bound (gpu_layout's are the defaults)."""
    (w, h), side = plan.tile_pixels, plan.block_tiles
    return {"TILE_W": w, "TILE_H": h, "TILE_RAYS": w * h, "TILE_ENTRIES": plan.tile_entries,
            "BLOCK_TILES_X": side, "BLOCK_TILES_Y": side, "BLOCK_TILES": side * side}


PLANAR_BEAM_GROUP = declare_constant("PLANAR_BEAM_GROUP", 64)  # tiles a workgroup of tile_beams_planar.comp


def planar_beams(plan) -> bool:
    """Whether a block-culled frame's tile frusta come from its tiles' corner pixels' sub-rays
    (glsl/accel/tile_beams_planar.comp): a planar (rasterizable) camera model, one colour channel
    set, so every sub-ray direction is an affine map of its image position from one origin."""
    from ..cameras import CAMERA_MODELS

    return CAMERA_MODELS[plan.camera].rasterizable and not plan.share_channels


def block_grid(width: int, height: int, tile: tuple[int, int] = TILE_PIXELS,
               side: int = BLOCK_TILES[0]) -> tuple[int, int]:
    """Blocks (across, down) of side x side `tile`s of a width x height image (edge blocks partial)."""
    nx, ny = tile_grid(width, height, tile)
    return -(-nx // side), -(-ny // side)


def frame_blocks(sizing, tile: tuple[int, int], side: int) -> int:
    bx, by = block_grid(*sizing.size, tile, side)
    return bx * by * sizing.layers


def subrays(plan: FramePlan) -> int:
    """The sub-rays a sample casts (glsl/common/camera.glsl CAMERA_SUBRAYS): its footprint's, times
    three colour channel sets cast together with shared channel shading."""
    return plan.subsamples * (SHARED_SETS if plan.share_channels else 1)


def msaa_slots(plan: FramePlan) -> int:
    """Distinct triangles a pixel keeps, each a round: at most its sub-rays and the plan's shading_slots."""
    return min(subrays(plan), plan.shading_slots)


def merges_surfaces(plan: FramePlan) -> bool:
    """Whether the MSAA merge shades a smooth surface's triangles in a pixel as one entry."""
    return uses_msaa(plan) and plan.shading_merge == "surface"


def uses_msaa(plan: FramePlan) -> bool:
    """Whether the frame traces every sub-ray of a sample and shades each distinct triangle once: MSAA,
    and shared channel shading (its channel sets are sub-rays)."""
    return (plan.subsamples > 1 and plan.shading == "msaa") or plan.share_channels


def skips_empty_slots(plan: FramePlan) -> bool:
    """Whether a round leaves the pixels with nothing in its slot (a slot above 0) as they are
    instead of making them background of weight 0. Exact when no pass of the round reads another
    pixel's G-buffer: the one that does is the screen-space quadtree (its effects, ssr; stereo
    reuse, the other, takes no MSAA). Slot 0, the last real round, writes every pixel."""
    return plan.skip_empty_slots and not any(EFFECTS[e].uses_quadtree for e in plan.effects if e in EFFECTS)


def skips_rounds(plan: FramePlan) -> bool:
    """Whether a round may leave pixels alone (glsl/common/round_skip.glsl): the MSAA slots a pixel
    has not. Its select then lists the tiles that hold a pixel it shades (ROUND_TILES, round_gate.py)."""
    return uses_msaa(plan)


def round_skip_reads(plan: FramePlan) -> list:
    """What a pass of the rounds reads to leave the pixels a round skips (glsl/common/round_skip.glsl)."""
    return [read("sample_weight"), read("round_tiles")] if skips_rounds(plan) else []


def round_skip_defines(plan: FramePlan, listed: bool = False) -> dict:
    """`listed`: the pass may run over the round's listed tiles (compute.py dispatch_frame)."""
    return {"ROUND_SKIP": int(skips_rounds(plan)), "ROUND_TILES": int(listed and skips_rounds(plan))}


def bind_round_skip(fc) -> None:
    if skips_rounds(fc.plan):
        fc.resource("sample_weight").bind_to_image(IMAGE["sample_weight"], read=True, write=False)
        fc.resource("round_tiles").bind_to_storage_buffer(SSBO["round_tiles"])


class PrimaryRaysPass(Pass):
    name = "primary_rays"
    timed_kernels = True

    def why(self, plan: FramePlan) -> str | None:
        if plan.primary != "rays":
            return None
        sub = f", {plan.subsamples} sub-rays per sample ({plan.shading})" if plan.subsamples > 1 else ""
        sub += f", its {plan.channels} colour channel sets cast together (shared shading)" if plan.share_channels else ""
        shape = "x".join(map(str, plan.tile_pixels))
        tiles = (f", tile frustum culling ({shape}-pixel tiles, {plan.tile_entries} entries, bvh2)"
                 if plan.tile_culling else "")
        tiles += f", from {plan.block_tiles}x{plan.block_tiles}-tile block beams" if plan.block_culling else ""
        tiles += f", tile triangle lists of {plan.tile_lists}" if plan.tile_lists else ""
        return f"primary visibility = rays ({plan.camera} camera{sub}{tiles})"

    def io(self, plan: FramePlan) -> list:
        out = [read("bvh"), write("visibility", GBufferChannels(("triangle", "position")))]
        if plan.sampled:
            out.append(write("sample_weight", SAMPLE_WEIGHT))
        if uses_msaa(plan):
            slots = msaa_slots(plan)
            # Slot-major: slot k of every pixel, then slot k + 1 (coalesced writes and reads).
            out += [write("msaa_hits", Buffer(lambda s, n=slots: s.pixels * n * 16, f"{slots} x 16 bytes per pixel")),
                    write("msaa_count", Buffer(lambda s: 4, "4 bytes")),
                    write("round_tiles", Buffer(round_tile_bytes, "a word per 8x8 tile", zeroed=True))]
        tile, entries, side = plan.tile_pixels, plan.tile_entries, plan.block_tiles
        tiles = functools.partial(frame_tiles, tile=tile)
        if plan.tile_culling:
            out += [write("tile_entries", Buffer(lambda s: tiles(s) * (entries + 1) * 4,
                                                 f"{entries + 1} words per {tile[0] * tile[1]}-pixel tile")),
                    write("tile_planes", Buffer(lambda s: tiles(s) * 80, "5 planes per tile"))]
        if plan.block_culling:
            out += [write("tile_boxes", Buffer(lambda s: tiles(s) * 48, "3 vec4 per tile")),
                    write("block_entries", Buffer(lambda s: frame_blocks(s, tile, side) * (entries + 1) * 4,
                                                  f"{entries + 1} words per block of tiles")),
                    write("block_planes", Buffer(lambda s: frame_blocks(s, tile, side) * 80, "5 planes per block"))]
        if plan.share_channels:
            out.append(write("channel_weight", CHANNEL_WEIGHT))
        if plan.tile_lists:
            out.append(write("tile_tris", Buffer(lambda s, n=plan.tile_lists: tiles(s) * (n + 1) * 8,
                                                 f"{plan.tile_lists + 1} x 8 bytes per tile")))
        return out

    def setup(self, gl, plan: FramePlan) -> None:
        # the primary rays' BVH layout; tile entry lists name binary child pairs
        self.layout = "bvh2" if plan.tile_culling else plan.traversal[0]
        self.block = msaa_block(plan.subsamples)
        tiles = {**tile_defines(plan), "TILE_ENTRIES_BINDING": SSBO["tile_entries"],
                 "TILE_PLANES_BINDING": SSBO["tile_planes"]} if plan.tile_culling else {}
        lists = {"TILE_TRIS": plan.tile_lists, "TILE_TRIS_BINDING": SSBO["tile_tris"]} if plan.tile_lists else {}
        base = {**layout_defines(DEFAULT_BINDING, self.layout), **camera_defines(plan), "SAMPLED": int(plan.sampled),
                "MSAA_SLOTS": msaa_slots(plan), "MSAA_BLOCK_W": self.block[0], "MSAA_BLOCK_H": self.block[1],
                "MSAA_GROUP": self.block[0] * self.block[1] * subrays(plan),
                "MSAA_SKIP_EMPTY": int(skips_empty_slots(plan)), **tiles, **lists,
                "MSAA_MERGE_SURFACES": int(merges_surfaces(plan)),
                "TILE_LIST_OVERFLOW": int(bool(plan.tile_lists))}
        self.msaa = uses_msaa(plan)
        self.programs = {mode: shaders.compute(gl.ctx, "rt/primary.comp", {**base, "PRIMARY_MODE": mode,
                                                                           "ROUND_TILES": int(mode == 2)})
                         for mode in ((1, 2) if self.msaa else (0,))}
        # With tile lists the cast (mode 0) or trace (mode 1) is two programs, each skipping the other's
        # tiles: the tiles with a list (tile_samples.comp), and per ray from the entries where a list
        # overflowed (primary.comp). One program with both paths held the BVH walk's registers in the
        # list path too (room, 16x: 13.7 ms, 10.7 without the walk).
        self.tile = plan.tile_pixels
        self.group = sample_group(subrays(plan) if self.msaa else 1, self.tile)
        self.samples = (shaders.compute(gl.ctx, "rt/tile_samples.comp",
                                        {**base, "SAMPLE_MODE": int(self.msaa), "SAMPLE_GROUP": self.group})
                        if plan.tile_lists else None)
        # The cull's kernels: tile frusta and cuts from the root in one (tile_cull.comp's TILE_STAGE 0), or
        # with block culling the tile frusta (stage 1), the blocks' cuts (block_cull.comp), the tiles'
        # cuts from their blocks' entries (stage 2).
        cull = {**layout_defines(DEFAULT_BINDING, "bvh2"), **camera_defines(plan), **tiles, "TILE_CAMERA": 1}
        blocks = {"TILE_BOXES_BINDING": SSBO["tile_boxes"], "BLOCK_ENTRIES_BINDING": SSBO["block_entries"],
                  "BLOCK_PLANES_BINDING": SSBO["block_planes"]}
        self.cull = {}
        # a planar model's tile frusta from the sub-rays of each tile's corner pixels (tile_beams_planar.comp)
        self.planar = planar_beams(plan)
        if plan.tile_culling and plan.block_culling:
            beams = ("accel/tile_beams_planar.comp", {}) if self.planar else ("accel/tile_cull.comp", {"TILE_STAGE": 1})
            self.cull = {"beams": shaders.compute(gl.ctx, beams[0], {**cull, **blocks, **beams[1]}),
                         "blocks": shaders.compute(gl.ctx, "accel/block_cull.comp", {**cull, **blocks}),
                         "cull": shaders.compute(gl.ctx, "accel/tile_cull.comp", {**cull, **blocks, "TILE_STAGE": 2})}
        elif plan.tile_culling:
            self.cull = {"cull": shaders.compute(gl.ctx, "accel/tile_cull.comp", cull)}
        self.lists = (shaders.compute(gl.ctx, "accel/tile_tris.comp", {**layout_defines(DEFAULT_BINDING, "bvh2"),
                                                                      **tiles, **lists})
                      if plan.tile_lists else None)
        # msaa_count is zeroed and read back through copies (GPU-side), never written or read by the
        # CPU itself: the CPU reading it every frame made the NVIDIA driver keep it in host memory,
        # and each atomic on it then took ~1.1 us across the bus (80 ms for one per
        # workgroup of the 2x1440x1600 MSAA trace, 1.8 ms with these copies;
        # docs/design.md). The readback holds one count per channel set.
        self.count_io = [gl.ctx.buffer(bytes(4)), gl.ctx.buffer(reserve=4 * plan.channels)] if self.msaa else []
        self.fences = {}  # channel set -> the fence after its count's copy (until read)
        self.gate = RoundGate(gl.ctx) if self.msaa else None

    def execute(self, fc) -> None:
        rnd = fc.round
        for program in [*self.programs.values(), *self.sample_tests()]:
            set_eye_uniforms(program, fc)
        fc.accel.layout(self.layout).bind(DEFAULT_BINDING)
        gb = fc.gbuffer
        for name in ("position", "triangle"):
            gb.textures[name].bind_to_image(channel(name).image, read=False, write=True)
        if "sample_weight" in fc.resources:
            fc.resource("sample_weight").bind_to_image(IMAGE["sample_weight"], read=False, write=True)
        if self.cull:
            self.cull_tiles(fc)
        if not self.msaa:
            if rnd.first:  # SSAA: one round per sub-ray; 1x: one
                rnd.start(fc.plan.subsamples)
            for program in [self.programs[0], *self.sample_tests()]:
                program["subsample"].value = rnd.slot
            fc.stage("cast", lambda: (self.dispatch_sample_tests(fc), dispatch_per_pixel(fc, self.programs[0])))
            return
        fc.resource("msaa_hits").bind_to_storage_buffer(SSBO["msaa_hits"])
        if merges_surfaces(fc.plan):
            fc.gpu_scene.surfaces().bind_to_storage_buffer(SSBO["triangle_surface"])
        count = fc.resource("msaa_count")
        count.bind_to_storage_buffer(SSBO["msaa_count"])
        if rnd.first:
            zero, readback = self.count_io
            fc.gl.ctx.copy_buffer(count, zero)
            fc.stage("trace", lambda: self.dispatch_trace(fc))
            if rnd.active:  # the rounds this channel needs: the most distinct triangles any pixel saw
                fc.gl.ctx.copy_buffer(readback, count, write_offset=4 * rnd.channel)
                rnd.start_polled(self.count_reader(fc, rnd.channel), msaa_slots(fc.plan))
            else:
                rnd.start(1)
        if fc.plan.share_channels:
            fc.resource("channel_weight").bind_to_image(IMAGE["channel_weight"], read=False, write=True)
        if not rnd.first and not rnd.known:  # recorded before the count was known: may lie past it
            self.gate.open(fc, rnd.ordinal)
            rnd.gate = self.gate
        # Slot = count - 1 - this: rounds of this channel set before this one; -1: slot 0 (no rounds).
        self.programs[2]["msaa_round"].value = rnd.ordinal if rnd.active else -1
        tiles = fc.resource("round_tiles")
        tiles.bind_to_storage_buffer(SSBO["round_tiles"])
        fc.stage("select", lambda: (dispatch_per_pixel(fc, self.programs[2]),
                                    self.gate.list_tiles(tiles, pixel_grid(fc.sizing))))
        rnd.tiles = tiles if round_gate.LIST_TILES else None

    def count_reader(self, fc, channel: int):
        """Round.start_polled's count(wait) for the channel set's count just copied to the readback."""
        old = self.fences.pop(channel, None)  # a fence of an earlier frame nobody asked about
        if old is not None:
            old.release()
        fence = self.fences[channel] = fc.gl.fence()
        readback = self.count_io[1]
        if COUNT_POLL not in COUNT_POLLS:
            raise ValueError(f"primary_rays.COUNT_POLL must be one of {', '.join(COUNT_POLLS)}, got {COUNT_POLL!r}")
        ready = {"fence": fence.ready, "wait": lambda: True, "never": lambda: False}[COUNT_POLL]

        def count(wait: bool) -> int | None:
            if not wait and not ready():
                return None
            fence.release()
            return max(1, int(np.frombuffer(readback.read(), np.uint32)[channel]))
        return count

    def cull_tiles(self, fc) -> None:
        """Tile culling: the tiles' entry lists, made in each channel set's first round (they bound
        every sub-ray the set's rounds cast), read by every round's trace."""
        fc.resource("tile_entries").bind_to_storage_buffer(SSBO["tile_entries"])
        fc.resource("tile_planes").bind_to_storage_buffer(SSBO["tile_planes"])
        if self.lists is not None:
            fc.resource("tile_tris").bind_to_storage_buffer(SSBO["tile_tris"])
        if "blocks" in self.cull:
            for name in ("tile_boxes", "block_entries", "block_planes"):
                fc.resource(name).bind_to_storage_buffer(SSBO[name])
        if not fc.round.first:
            return   # one cull per channel set (with shared channel shading one set of all three)
        nx, ny = tile_grid(*fc.sizing.size, self.tile)
        layers, barrier = fc.sizing.layers, lambda: fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)
        if "beams" in self.cull:   # HVVR's block beams: tile frusta, the blocks' cuts, then the tiles'
            beams, blocks = self.cull["beams"], self.cull["blocks"]
            set_eye_uniforms(beams, fc)
            beams["image_size"].value = tuple(fc.sizing.size)
            blocks["tile_count"].value = (nx, ny)
            grid = (-(-nx * ny // PLANAR_BEAM_GROUP), 1) if self.planar else (nx, ny)
            fc.stage("beams", lambda: (beams.run(*grid, layers), barrier()))
            grid_b = block_grid(*fc.sizing.size, self.tile, fc.plan.block_tiles)
            fc.stage("blocks", lambda: (blocks.run(*grid_b, layers), barrier()))
        else:
            set_eye_uniforms(self.cull["cull"], fc)
            self.cull["cull"]["image_size"].value = tuple(fc.sizing.size)
        fc.stage("cull", lambda: (self.cull["cull"].run(nx, ny, layers), barrier()))
        if self.lists is not None:  # each tile's triangles, from its entries (HVVR's tile beams)
            fc.stage("lists", lambda: (self.lists.run(nx, ny, fc.sizing.layers),
                                       fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)))

    def dispatch_trace(self, fc) -> None:
        """The tiles with a list: tile_samples.comp; the others (all, without lists): one workgroup
        per block of pixels (msaa_block), one invocation per sub-ray."""
        (w, h), (bw, bh) = fc.sizing.size, self.block
        self.dispatch_sample_tests(fc)
        self.programs[1].run(-(-w // bw), -(-h // bh), fc.sizing.layers)
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def sample_tests(self) -> list:
        return [self.samples] if self.samples is not None else []

    def dispatch_sample_tests(self, fc) -> None:
        """With tile lists: tile_samples.comp, one workgroup per band of `self.group` pixels of a tile."""
        if self.samples is not None:
            nx, ny = tile_grid(*fc.sizing.size, self.tile)
            self.samples.run(nx, ny * (self.tile[0] * self.tile[1] // self.group), fc.sizing.layers)

    def release(self) -> None:
        for p in [*self.programs.values(), *self.sample_tests(), *self.count_io, *self.fences.values(),
                  *self.cull.values(), *([self.lists] if self.lists else []), *([self.gate] if self.gate else [])]:
            p.release()
