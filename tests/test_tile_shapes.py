"""Tile and block shapes of tile-culled primary visibility (RenderSettings.tile_size, tile_entries,
block_tiles; chosen per camera model by measurement, frame/passes/primary_rays.py tile_shape): every
shape gives per-ray traversal's frame on every camera model, a tiny entry bound included (the cuts
stop early and still cover every triangle); each shape's planes hold its own tiles' sub-rays and each
tile's cut lies below its own block's; a bound no block can hold is refused in words."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import camera_rig
from test_block_culling import render as render_both, subtree_sets, words
from test_tile_culling_frame import gl_tile_rays

from rayvr.accel.frustum import tile_grid
from rayvr.frame.cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from rayvr.frame.passes.primary_rays import block_grid
from rayvr.gl.gpu_layout import NO_HIT
from rayvr.options import OptionError
from rayvr.renderer import RenderSettings

SIZE = (64, 40)   # 8 x 5 tiles of 8x8 an eye: 2 x 2 blocks of 4x4 tiles, the lower ones partial

# name -> (camera model, sub-rays per sample, vertical fov or None)
CASES = {
    "pinhole 16x msaa": (Pinhole(), 16, None),
    "distorted chromatic 4x shared": (Distorted(), 4, None),
    "foveated": (Foveated(), 1, None),
    "wide 210x130": (Wide(fov_x=210.0), 1, 130.0),
    "dof 4x at 0.5": (ThinLens(aperture=0.08, focus=0.5), 4, None),
}
# name -> settings: the smallest and largest tiles, blocks and bounds, with and without lists
SHAPES = {
    "8x8 tiles, 8 entries, 4x4 blocks": dict(tile_size="8x8", tile_entries=8, block_culling=True, block_tiles=4),
    "8x8 tiles, 64 entries, no blocks": dict(tile_size="8x8", tile_entries=64, block_culling=False),
    "16x16 tiles, 64 entries, 16x16 blocks, lists": dict(tile_size="16x16", tile_entries=64, block_culling=True,
                                                         block_tiles=16, tile_lists=64),
    "16x8 tiles, 8 entries, 8x8 blocks, lists": dict(tile_size="16x8", tile_entries=8, block_culling=True,
                                                     block_tiles=8, tile_lists=64),
}


def render(r, rig, samples, **kw):
    """(triangle IDs, depth, colour of both eyes), the channel sets shared where the renderer picks it."""
    return render_both(r, rig, samples, share=None, **kw)


@pytest.mark.parametrize("shape", list(SHAPES))
@pytest.mark.parametrize("case", list(CASES))
def test_every_tile_shape_gives_the_per_ray_frame(room, case, shape):
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov, size=SIZE)
    ref = render(room, rig, samples, tile_culling=False)
    assert (ref[0] != NO_HIT).mean() > 0.5
    got = render(room, rig, samples, **SHAPES[shape])
    plan = room.plan(camera=camera)
    settings = SHAPES[shape]
    assert plan.tile_culling and plan.tile_pixels == tuple(map(int, settings["tile_size"].split("x")))
    assert plan.tile_entries == settings["tile_entries"] and plan.block_culling == settings["block_culling"]
    assert np.array_equal(ref[0], got[0]), f"{case}, {shape}: {np.mean(ref[0] != got[0]):.2%} of pixels differ"
    assert np.array_equal(ref[1], got[1]) and np.array_equal(ref[2], got[2])
    nx, ny = tile_grid(*SIZE, plan.tile_pixels)
    lists = words(room, "tile_entries", nx * ny * 2, plan.tile_entries + 1)
    assert lists[:, 0].max() <= plan.tile_entries
    if case != "wide 210x130":   # culling took place: some tile lists entries below the root's children
        assert (~((lists[:, 0] == 2) & (np.sort(lists[:, 1:3], axis=1) == [0, 1]).all(1)) & (lists[:, 0] > 0)).any()


@pytest.mark.parametrize("tile, side", [((8, 8), 4), ((16, 16), 16), ((8, 8), 16)], ids=["8x8 in 4x4", "16x16 in 16x16",
                                                                                       "8x8 in 16x16"])
def test_each_shapes_planes_hold_its_tiles_rays_and_cuts_lie_below_their_block(room, tile, side):
    """A thin lens at 4x (several origins): the planes the GPU wrote for each tile of the shape hold
    every point o + t d of its pixels' sub-rays, each block's planes its tiles', and every entry of a
    tile's cut lies in the subtree of an entry of its own block (block side x side tiles)."""
    camera, samples = ThinLens(aperture=0.08, focus=1.5), 4
    rig = camera_rig(room, camera, None, size=SIZE)
    render(room, rig, samples, tile_size=f"{tile[0]}x{tile[1]}", tile_entries=16, block_culling=True, block_tiles=side)
    nx, ny = tile_grid(*SIZE, tile)
    bx, by = block_grid(*SIZE, tile, side)
    planes = np.frombuffer(room.resource("tile_planes").read(), np.float32)[:nx * ny * 2 * 20].reshape(-1, 5, 4)
    bplanes = np.frombuffer(room.resource("block_planes").read(), np.float32)[:bx * by * 2 * 20].reshape(-1, 5, 4)
    tiles = words(room, "tile_entries", nx * ny * 2, 17)
    blocks = words(room, "block_entries", bx * by * 2, 17)
    below = subtree_sets(room.accel.gpu.bvh)
    checked = 0
    for eye in range(2):
        for t, (o, d) in gl_tile_rays(room, rig, eye, 0, samples, tile=tile).items():
            tx, ty = t % nx, t // nx
            b = eye * bx * by + (ty // side) * bx + tx // side
            for pl in (planes[eye * nx * ny + t], bplanes[b]):
                for s in (0.0, 0.5, 3.0, 50.0):
                    p = o + s * d
                    out = p @ pl[:4, :3].astype(np.float64).T - pl[:4, 3]
                    assert (out <= 1e-5 * (1 + np.abs(p).sum(1, keepdims=True))).all(), (eye, t, out.max())
            tile_list = tiles[eye * nx * ny + t]
            covered = set().union(*(below[int(e)] for e in blocks[b, 1:1 + blocks[b, 0]]))
            assert tile_list[0] > 0 and set(tile_list[1:1 + tile_list[0]].tolist()) <= covered, (eye, t)
            checked += len(o)
    assert checked == 2 * SIZE[0] * SIZE[1] * samples


def test_shapes_follow_the_settings_and_a_bound_a_block_cannot_hold_is_refused(room):
    rig = camera_rig(room, Pinhole(), None, size=SIZE)
    room.settings = RenderSettings(primary="rays", block_culling=True, block_tiles=4, tile_entries=64)
    with pytest.raises(ValueError, match=r"block of 4x4 tiles cuts to at most 16 entries, one a tile, and 64 were asked"):
        room.render(rig)
    room.settings = RenderSettings(primary="rays", block_culling=True, block_tiles=4)   # a bound left to the choice
    assert room.plan().tile_entries <= 16 and room.plan().block_tiles == 4
    room.settings = RenderSettings(primary="rays", tile_culling=False, tile_size="8x8")   # no tiles: no shape
    assert not room.plan().tile_culling and room.plan().tile_pixels == (16, 8)
    with pytest.raises(OptionError, match="unknown tile size '9x9'; allowed: 8x8, 16x8, 16x16"):
        RenderSettings(tile_size="9x9")
    with pytest.raises(OptionError, match="unknown tile entry bound 12"):
        RenderSettings(tile_entries=12)
    room.settings = RenderSettings()
