"""Options of primary visibility and MSAA (rayvr/frame/passes/primary_rays.py)."""
from __future__ import annotations

from ..options import Option, declare

MAX_SLOTS = 8  # entries kept per pixel (MSAA, frame/passes/primary_rays.py); sub-rays on further ones are dropped
# What an MSAA entry is: the sub-rays on one triangle, or on one smooth surface at one depth (scene/surfaces.py)
SHADING_MERGES = ("triangle", "surface")

PRIMARY_MODES = ("raster", "rays")

PRIMARY = declare(Option("primary", str, "raster", "primary visibility: the raster G-buffer pass, or camera rays "
                         "through the BVH (rays anyway where --msaa or the camera model needs them)", scope="plan",
                         plan_field="primary", choices=PRIMARY_MODES, label="primary visibility",
                         commands=("capture", "preview", "info")))

TILE_CULLING = declare(Option("tile_culling", bool, None, "ray-cast primary visibility culls the BVH per tile of "
                              "pixels first (--tile-size; a frustum over every sub-ray, lens point and channel of "
                              "the tile; the same hits, exact) and walks the binary layout; auto: where it measured "
                              "faster "
                              "(rayvr/assets/primary_visibility.json: every camera model but foveated, with block "
                              "culling); bench primary: each rays row without and with it",
                              scope="plan", plan_field="tile_culling", auto=True,
                              commands=("capture", "preview", "info", "bench")))
BLOCK_CULLING = declare(Option("block_culling", bool, None, "ray-cast primary visibility with tile culling first "
                               "cuts the BVH per block of tiles (--block-tiles; HVVR's block beams: a frustum over "
                               "the tiles' frusta), and each tile's cut starts from its block's entries instead of "
                               "the root (the same hits, exact); auto: where it measured faster "
                               "(rayvr/assets/primary_visibility.json: every camera model but foveated)",
                               scope="plan", plan_field="block_culling", auto=True,
                               implies=(("tile_culling", True),), commands=("capture", "preview", "info", "bench")))

# A tile's and a block's shape and a cut's bound (item 4 of HVVR's pipeline: chosen by measurement per
# camera model, like the stages; primary_visibility.json). A tile is a workgroup of its pixels (at most
# 256 invocations), a power of two on each side so the MSAA trace's blocks (msaa_block) lie in one; a
# cut tests its entries one an invocation, so a bound is at most a tile's pixels and a block's tiles.
TILE_SIZES = ("8x8", "16x8", "16x16")
TILE_ENTRY_BOUNDS = (8, 16, 32, 64)
BLOCK_SIDES = (4, 8, 16)  # a block of N x N tiles

TILE_SIZE_OPTION = declare(Option("tile_size", str, None, "ray-cast primary visibility with tile culling: a tile's "
                           "pixels (w x h), one frustum and entry list each; auto: the measured choice "
                           "(rayvr/assets/primary_visibility.json); implies tile culling", scope="plan",
                           plan_field="tile_pixels", choices=TILE_SIZES, auto=True, label="tile size", metavar="WxH",
                           implies=(("tile_culling", True),),
                           commands=("capture", "preview", "info", "bench")))

TILE_ENTRIES_OPTION = declare(Option("tile_entries", int, None, "ray-cast primary visibility with tile culling: "
                                     "the BVH entry nodes a tile's (and a block's) cut lists at most (more: a "
                                     "tighter cut, longer lists to walk); implies tile culling; auto: the measured "
                                     "choice", scope="plan", plan_field="tile_entries", choices=TILE_ENTRY_BOUNDS,
                                     auto=True, implies=(("tile_culling", True),),
                                     label="tile entry bound", metavar="N",
                                     commands=("capture", "preview", "info", "bench")))

BLOCK_TILES_OPTION = declare(Option("block_tiles", int, None, "ray-cast primary visibility with block culling: "
                                    "a block beam's tiles, N x N; implies block culling; auto: the measured choice",
                                    scope="plan", plan_field="block_tiles", choices=BLOCK_SIDES, auto=True,
                                    label="block side", implies=(("block_culling", True),),
                                    metavar="N", commands=("capture", "preview", "info", "bench")))

TILE_LIST_BOUNDS = (16, 32, 64, 128, 256, 512, 1024)  # triangles a tile's list may hold (a power of two: its sort)
TILE_LISTS = declare(Option("tile_lists", int, None, "ray-cast primary visibility tests each tile's rays "
                            "against the tile's own list of at most N triangles (those of its frustum, nearest "
                            "first, from workgroup memory; the same hits, exact); a tile with more walks the BVH "
                            "from its entries; 0: off; implies tile culling; auto: where it measured faster",
                            scope="plan", plan_field="tile_lists", choices=(0,) + TILE_LIST_BOUNDS, auto=True,
                            implies=(("tile_culling", True),), label="tile list bound", metavar="N",
                            commands=("capture", "preview", "info", "bench")))

SHARE_CHANNELS = declare(Option("share_channel_shading", bool, None, "a chromatic camera (three colour channel "
                                "sets) casts its sets together as sub-rays of each sample and shades a pixel once "
                                "per distinct triangle its sets' rays hit, each channel taking its own share "
                                "(HVVR's shared shading: the approximation and its error are in docs/design.md; "
                                "--msaa up to 16); false: every channel set cast and shaded on its own; auto: "
                                "up to --msaa 8, where it measured faster",
                                scope="plan", plan_field="share_channels", auto=True,
                                commands=("capture", "preview", "info", "bench")))

SHADING_SLOTS = declare(Option("shading_slots", int, MAX_SLOTS, "MSAA for rays and shared channel shading: "
                               "a pixel shades at most its N most covered distinct triangles, the rounds the "
                               "frame runs at most (the sub-rays on the others go to the kept ones, by "
                               "coverage); fewer: fewer rounds at edges where many triangles meet",
                               bounds=(1, MAX_SLOTS), scope="plan", plan_field="shading_slots", metavar="N",
                               commands=("capture", "preview", "info", "bench")))

SHADING_MERGE = declare(Option("shading_merge", str, "triangle", "MSAA for rays and shared channel shading: what "
                               "a pixel shades once: each distinct triangle it sees, or each smooth surface "
                               "(neighbouring triangles of one material shaded smooth across their edge, creases "
                               "under 30 degrees, at one depth): fewer rounds where a pixel covers a tessellated "
                               "object's edges, fewer shading points there",
                               choices=SHADING_MERGES, scope="plan", plan_field="shading_merge", metavar="HOW",
                               label="shading merge", commands=("capture", "preview", "info", "bench")))
