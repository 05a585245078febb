"""Every constant the CPU and the shaders share, declared once (here, or with glsl_constants.declare in the
module that uses it) and emitted as a generated GLSL header: shaders `#include "layout.glsl"` (the
shader loader serves it from `glsl_header()`; there is no such file on disk).

  G-buffer channels   name, format, texture unit (read), image unit (resolve writes)
  bindings            shader storage buffers (SSBO_*), image units (IMAGE_*), texture units (UNIT_*)
  enums               debug views, tonemappers, light kinds; effects from the lines the effect
                      registry (rayvr/frame/effect_registry.py) adds with `generated_lines`
  sentinels           NO_HIT, BACKGROUND_EFFECT, ROUND_SKIPPED
  declared constants  those other modules declare where they use them (rayvr/gl/glsl_constants.py
                      declare: the SSRT statuses, QT_*, the CAMERA_* enum, SCAN_BLOCK, ...)

Names in GLSL are the Python names in upper case with a prefix: GB_UNIT_<CHANNEL>,
GB_IMAGE_<CHANNEL>, SSBO_<NAME>, IMAGE_<NAME>, UNIT_<NAME>, EFFECT_<NAME>, VIEW_<NAME>,
TONEMAP_<NAME>, LIGHT_<KIND>, PARAM_<EFFECT>_<PARAM>.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import glsl_constants
from .glsl_constants import declare


@dataclass(frozen=True)
class Channel:
    name: str
    components: int
    dtype: str  # moderngl dtype; 'depth' = 32-bit float depth attachment
    unit: int  # texture unit compute passes read it from
    image: int  # image unit the resolve writes it at (-1: written by the raster only)
    glsl_format: str  # image format qualifier ('' for depth)
    meaning: str


# The G-buffer: a visibility raster writes `depth` and `triangle`; the compute resolve the rest.
CHANNELS = (
    Channel("depth", 1, "depth", 0, -1, "", "reversed-Z depth: near/view_distance (1 at near, 0 at infinity)"),
    Channel("position", 4, "f4", 1, 0, "rgba32f", "xyz scene-local position (world - scene.origin), w linear view depth"),
    Channel("normal", 4, "f2", 2, 1, "rgba16f", "xyz world-space shading normal facing the eye, w roughness"),
    Channel("albedo", 4, "f2", 3, 2, "rgba16f", "rgb linear base colour, a metallic"),
    Channel("emission", 4, "f2", 4, 3, "rgba16f", "rgb emitted radiance"),
    Channel("material", 2, "u4", 5, 4, "rg32ui", "x material index, y effect ID (255 = background)"),
    Channel("triangle", 1, "u4", 6, 5, "r32ui", "triangle ID (0xFFFFFFFF = background)"),
    Channel("linear_depth", 1, "f4", 7, 6, "r32f", "view depth of the pixel ray's hit, exact (0 = background); "
                                                   "what frames return as depth, 4 bytes a pixel"),
)

# Shader storage buffer bindings.
SSBO = {
    "triangle_material": 0, "materials": 1, "lights": 2, "vertices": 3, "indices": 4,
    "triangle_surface": 5,  # scene/gpu_scene.py: each triangle's smooth surface (scene/surfaces.py), for the MSAA merge
    "picked": 7,  # preview: the texel under the cursor
    "bvh_nodes": 8, "bvh_triangles": 9,  # accel/gpu.py (batch tracers may use other bases)
    "rt_lists": 10, "rt_list_args": 11,  # frame/passes/classify.py
    "wave_paths": 12, "wave_shadows": 13, "wave_args": 14, "wave_rays": 52,  # frame/passes/trace_effect.py
    "wave_order": 17, "wave_fetch": 18,  # its ray order (frame/passes/ray_order.py), persistent threads' counters
    "sort_count": 19,  # frame/passes/radix_sort.py: a pair count the GPU wrote (SORT_COUNTED)
    "dda_rays": 15, "dda_results": 16,  # bench/tracers/dda.py DdaTracer (glsl/ssrt/dda_batch.comp)
    "quadtree_nodes": 20, "quadtree_rays": 21, "quadtree_results": 22,  # frame/passes/quadtree.py, glsl/ssrt/quadtree*.glsl
    "hiz_levels": 23, "hiz_rays": 24, "hiz_results": 25,  # bench/tracers/hiz.py HizTracer, glsl/ssrt/hiz*.glsl
    "refit_vertices": 26, "refit_index": 27,  # accel/refit.py GpuRefit (glsl/accel/refit.comp)
    "tile_entries": 28, "tile_planes": 29,  # tile frustum culling (accel/gpu.py RayTracer, glsl/accel/tile_cull.comp)
    # block culling (frame/passes/primary_rays.py, glsl/accel/block_cull.comp): the tiles' origin boxes
    # and slopes, the blocks' entry lists and planes
    "tile_boxes": 33, "block_entries": 34, "block_planes": 35,
    # the photon map (frame/effects/photon/, glsl/photon/): traced photons, (cell, slot) keys and their
    # ping-pong copy, the scanned words (cell counts -> start indices; the sort's digit table),
    # photons sorted by cell, the kd-tree's array, the lights' emission table; test/bench queries
    "photons": 40, "photon_keys": 41, "photon_keys_alt": 42, "photon_scan": 43, "photon_map": 44,
    "photon_kdtree": 45, "photon_lights": 46, "photon_queries": 47, "photon_found": 48,
    "photon_query_counts": 49,
    "reuse_map": 50, "warp_counts": 51,  # stereo modes: frame/passes/reuse.py, frame/passes/warp.py (glsl/stereo/)
    # frame/passes/primary_rays.py: distinct triangles per pixel (MSAA for rays), the tile triangle lists
    "msaa_hits": 30, "msaa_count": 31, "tile_tris": 32,
    # frame/passes/round_gate.py: the dispatch sizes of an MSAA round that may lie past the count, and
    # the round's tiles with a pixel to shade (glsl/common/round_skip.glsl ROUND_TILES)
    "round_gate": 36, "round_tiles": 39,
}
# Image units of the frame's colour targets (the resolve's G-buffer images use GB_IMAGE_*).
IMAGE = {"hdr": 0, "ldr": 1,
         # frame/passes/accumulate.py (glsl/post/accumulate.comp) and frame/passes/denoise.py (glsl/post/denoise.comp)
         "accum_in": 2, "accum_moments_in": 3, "accum_out": 4, "accum_moments_out": 5,
         "accum_history_out": 6, "accum_history_moments_out": 7,
         "denoise_in": 2, "denoise_out": 3, "denoise_moments": 4, "denoise_color": 5, "denoise_guide": 6,
         "denoise_gradient": 7, "denoise_variance": 1,
         "layer2": 2, "layer2_triangle": 3,  # frame/passes/second_layer.py
         "warp_color": 2, "warp_depth": 3,  # frame/passes/warp.py (glsl/stereo/warp.comp)
         "dof_in": 2, "dof_out": 3,  # frame/passes/dof.py (glsl/post/dof.comp)
         # frame/passes/sample_accumulate.py, sample_resolve.py; sample_weight beside the G-buffer
         # images (0..6) primary_rays writes with it
         "sample_sum": 2, "frame_hdr": 3, "sample_fill": 4, "sample_weight": 7,
         # shared channel shading (frame/passes/primary_rays.py shares_channels): each colour channel's
         # weight of the round's surface; beside primary_rays' images (0, 5, 7) and sample_accumulate's (0, 2, 7)
         "channel_weight": 1}
# Texture units beside the G-buffer channels' (0..7).
UNIT = {"base_color_textures": 9, "layer2": 10, "layer2_triangle": 11, "peel_triangle": 12,
        "camera_samples": 13}  # camera_samples: frame/cameras/distorted.py sample files

TONEMAPPERS = ("clamp", "reinhard", "aces")
DEBUG_VIEWS = ("depth", "normal", "albedo", "roughness", "metallic", "emission", "material", "effect",
               "triangle", "position")
# Views made by passes of their own (not debug_view.comp): the quadtree's node visits per pixel,
# the camera model's sample pattern (frame/passes/sample_pattern.py).
TRACE_VIEWS = ("quadtree_visits", "samples")
VIEWS = ("color",) + DEBUG_VIEWS + TRACE_VIEWS
LIGHT_KINDS = ("point", "directional", "rect")
NO_HIT = 0xFFFFFFFF
ROUND_SKIPPED = -1.0  # sample_weight of a pixel an MSAA round leaves alone (glsl/common/round_skip.glsl)
SSRT_RAY_GROUP = 64  # invocations per group of the screen-space batch shaders (glsl/ssrt/*_batch.comp)
# BVH node layouts (accel/gpu.py) -> node width: binary child pairs (the reference), wide quantized,
# and the compressed 8-wide BVH of Ylitie et al. 2017 (accel/cwbvh.py).
BVH_LAYOUTS = {"bvh2": 2, "bvh4": 4, "bvh8": 8, "cwbvh": 8}
COMPRESSED_LAYOUT = "cwbvh"
# Tile frustum culling (HVVR): rays a tile (one work group), entry nodes a tile's list holds at most.
TILE_RAYS = 128
TILE_ENTRIES = 32
# Defaults (the RayTracer's tiles, shaders compiled alone): frame tiles and blocks take their plan's
# shape and bound, measured per camera model (frame/passes/primary_rays.py --tile-size, --tile-entries,
# --block-tiles).
TILE_PIXELS = (16, 8)  # a frame tile's pixel block (w, h): TILE_RAYS samples (primary_rays --tile-culling)
BLOCK_TILES = (8, 8)  # a block of frame tiles (w, h): HVVR's block beams (primary_rays --block-culling)
VERTEX_FLOATS = 8  # position xyz, normal xyz, uv (gpu_scene.interleaved_vertices)
# Least widening of a BVH box side (accel/bvh.py widen, the GPU refit): with the traversal's safe
# inverse of a zero direction component (1 / 1e-20) it exceeds any distance in a scene.
BVH_FACE_SLACK = 1e-12
# Raster shading (glsl/common/lighting.glsl, reference/shading.py): a rect light is NxN fixed points
# (soft shadows without noise).
RECT_LIGHT_GRID = declare("RECT_LIGHT_GRID", 4)
# Effects on the GPU (rayvr/frame/effect_registry.py): a material's parameter block (glsl/common/scene.glsl),
# effect IDs as bits of a 32-bit mask (the shade pass), the effect-ID value of pixels no geometry covers.
PARAM_WORDS = 8
MAX_EFFECT_ID = 32
BACKGROUND_EFFECT = 255


def channel(name: str) -> Channel:
    return next(c for c in CHANNELS if c.name == name)


# Header sections that a module above the layout generates from its own state at each header build
# (the effect registry: effect IDs, parameter slots, pixel-list slots), so this module imports none of them.
_GENERATED: dict = {}  # owner -> () -> list of lines


def generated_lines(owner: str, lines) -> None:
    """Make `lines()` part of every header from now on, under `owner` (its module)."""
    _GENERATED[owner] = lines


def glsl_header() -> str:
    """The generated header (a GLSL source string)."""
    out = ["// Generated from rayvr/gl/gpu_layout.py and the effect registry: do not edit.",
           "#ifndef RAYVR_LAYOUT_GLSL", "#define RAYVR_LAYOUT_GLSL"]
    for c in CHANNELS:
        out.append(f"#define GB_UNIT_{c.name.upper()} {c.unit}")
        if c.image >= 0:
            out.append(f"#define GB_IMAGE_{c.name.upper()} {c.image}")
    out += [f"#define SSBO_{k.upper()} {v}" for k, v in SSBO.items()]
    out += [f"#define IMAGE_{k.upper()} {v}" for k, v in IMAGE.items()]
    out += [f"#define UNIT_{k.upper()} {v}" for k, v in UNIT.items()]
    out += [f"#define TONEMAP_{k.upper()} {i}" for i, k in enumerate(TONEMAPPERS)]
    out += [f"#define VIEW_{k.upper()} {i}" for i, k in enumerate(DEBUG_VIEWS)]
    out += [f"#define LIGHT_{k.upper()} {i}" for i, k in enumerate(LIGHT_KINDS)]
    out += [f"#define NO_HIT 0x{NO_HIT:X}u", f"#define ROUND_SKIPPED {ROUND_SKIPPED!r}", f"#define VERTEX_FLOATS {VERTEX_FLOATS}",
            f"#define SSRT_RAY_GROUP {SSRT_RAY_GROUP}",
            f"#define DEFAULT_TILE_RAYS {TILE_RAYS}", f"#define DEFAULT_TILE_ENTRIES {TILE_ENTRIES}",
            # the defaults of a tile's and a block's shape: the primary-ray pass gives its plan's own
            # (frame/passes/primary_rays.py tile_defines, measured per camera model)
            "#ifndef TILE_W", f"#define TILE_W {TILE_PIXELS[0]}", f"#define TILE_H {TILE_PIXELS[1]}", "#endif",
            "#ifndef BLOCK_TILES_X", f"#define BLOCK_TILES_X {BLOCK_TILES[0]}",
            f"#define BLOCK_TILES_Y {BLOCK_TILES[1]}",
            f"#define BLOCK_TILES {BLOCK_TILES[0] * BLOCK_TILES[1]}",  # a literal: local_size_x (GLSL 4.30)
            "#endif",
            f"#define BVH_FACE_SLACK {BVH_FACE_SLACK!r}"]
    out += [f"#define BACKGROUND_EFFECT {BACKGROUND_EFFECT}u", f"#define MAX_EFFECT_ID {MAX_EFFECT_ID}",
            f"#define MATERIAL_PARAM_WORDS {PARAM_WORDS}"]
    for lines in _GENERATED.values():
        out += lines()
    out += glsl_constants.glsl_lines()  # those the owning modules declare
    out.append("#endif")
    return "\n".join(out) + "\n"
