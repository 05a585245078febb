"""Block culling (RenderSettings.block_culling; HVVR's block beams: glsl/accel/block_cull.comp, then
each tile's cut from its block's entries, tile_cull.comp TILE_STAGE 2) against per-ray traversal from
the BVH root, the reference: the same triangle, distance and colour on every camera model, with and
without tile triangle lists; and the blocks' planes and entries checked in numpy."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.frame.passes import primary_rays
from conftest import camera_rig
from test_tile_culling_frame import SHAPE, gl_tile_rays
from test_tile_lists import CASES as LIST_CASES

from rayvr.accel.frustum import tile_grid
from rayvr.frame.cameras import Pinhole, ThinLens, Wide
from rayvr.frame.passes.primary_rays import block_grid
from rayvr.gl.gpu_layout import BLOCK_TILES, NO_HIT, TILE_ENTRIES
from rayvr.renderer import RenderSettings

SIZE = (160, 24)   # 10 x 3 tiles an eye: two blocks across, the second partial

# name -> (camera model, sub-rays per sample, vertical fov or None): the tile lists' cases but 32x
CASES = {name: case for name, case in LIST_CASES.items() if name != "pinhole 32x msaa"}


def render(r, rig, samples, share=False, **kw):
    """(triangle IDs, depth, colour of both eyes); `share`: share_channel_shading (None: auto)."""
    r.settings = RenderSettings(primary="rays", msaa=samples, share_channel_shading=share, **{**SHAPE, **kw})
    f = r.render(rig, aux=("triangle",))
    both = lambda a, b: np.stack([a, b])
    return (both(f.left.aux["triangle"], f.right.aux["triangle"]), both(f.left.depth, f.right.depth),
            both(f.left.color, f.right.color))


def words(r, name, count, per):
    return np.frombuffer(r.resource(name).read(), np.uint32)[:count * per].reshape(count, per)


@pytest.mark.parametrize("case", list(CASES))
def test_block_culled_frames_equal_per_ray(room, case):
    """Each tile's cut from its block's entries, then traced per ray from the entries or through the
    tile lists: the reference's frame."""
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov, size=SIZE)
    ref = render(room, rig, samples, tile_culling=False)
    assert (ref[0] != NO_HIT).mean() > 0.5
    for lists in (0, 64):
        got = render(room, rig, samples, tile_culling=True, block_culling=True, tile_lists=lists)
        assert room.plan(camera=camera).block_culling
        assert np.array_equal(ref[0], got[0]), f"{case}, lists {lists}: {np.mean(ref[0] != got[0]):.2%} of pixels differ"
        assert np.array_equal(ref[1], got[1]) and np.array_equal(ref[2], got[2])


def test_block_planes_hold_every_ray_of_their_tiles_and_tiles_start_below_their_block(room):
    """The planes the GPU wrote for each block hold every point o + t d of every sub-ray of its tiles'
    pixels; every entry of a tile's cut lies in the subtree of one of its block's entries; and the
    blocks did cut (some block lists entries below the root's children)."""
    camera, samples = ThinLens(aperture=0.08, focus=1.5), 4   # several origins: the boxes matter
    rig = camera_rig(room, camera, None, size=SIZE)
    render(room, rig, samples, block_culling=True)
    nx, ny = tile_grid(*SIZE)
    bx, by = block_grid(*SIZE)
    bplanes = np.frombuffer(room.resource("block_planes").read(), np.float32)[:bx * by * 2 * 20].reshape(-1, 5, 4)
    blocks = words(room, "block_entries", bx * by * 2, TILE_ENTRIES + 1)
    tiles = words(room, "tile_entries", nx * ny * 2, TILE_ENTRIES + 1)
    bvh = room.accel.gpu.bvh
    below = subtree_sets(bvh)
    checked = 0
    for eye in range(2):
        for t, (o, d) in gl_tile_rays(room, rig, eye, 0, samples).items():
            tx, ty = t % nx, t // nx
            b = eye * bx * by + (ty // BLOCK_TILES[1]) * bx + tx // BLOCK_TILES[0]
            pl = bplanes[b].astype(np.float64)
            for s in (0.0, 0.5, 3.0, 50.0):
                p = o + s * d
                side = p @ pl[:, :3].T - pl[:, 3]
                assert (side <= 1e-5 * (1 + np.abs(p).sum(1, keepdims=True))).all(), (eye, t, side.max())
            tile_list = tiles[eye * nx * ny + t]
            block_list = blocks[b, 1:1 + blocks[b, 0]]
            covered = set().union(*(below[int(e)] for e in block_list))
            assert set(tile_list[1:1 + tile_list[0]].tolist()) <= covered, (eye, t)
            checked += len(o)
    assert checked == 2 * SIZE[0] * SIZE[1] * samples
    root_children = (blocks[:, 0] == 2) & (np.sort(blocks[:, 1:3], axis=1) == [0, 1]).all(1)
    assert (~root_children).any(), blocks[:, :4]


def subtree_sets(bvh) -> dict:
    """{entry (parent << 1 | side): every entry at or below it} of the binary BVH's child pairs."""
    meta = bvh.pack_nodes()[:, 12:16].view(np.int32)   # L index, R index, L count, R count
    out: dict = {}

    def visit(e: int) -> set:
        if e in out:
            return out[e]
        parent, side = e >> 1, e & 1
        index, count = meta[parent, side], meta[parent, 2 + side]
        got = {e}
        if count == 0:
            got |= visit(index << 1) | visit((index << 1) | 1)
        out[e] = got
        return got

    visit(0), visit(1)
    return out


def test_a_block_of_tiles_not_culled_falls_back_to_the_root_and_stays_exact(room):
    """A 210-degree view at 16 x 8 pixels: one tile, not culled, so its block is not either."""
    rig = camera_rig(room, Wide(fov_x=210.0), 130.0, size=(16, 8))
    ref = render(room, rig, 1, tile_culling=False)
    got = render(room, rig, 1, block_culling=True)
    assert np.array_equal(ref[0], got[0]) and (ref[0] != NO_HIT).any()
    blocks = words(room, "block_entries", 2, TILE_ENTRIES + 1)
    assert (blocks[:, 0] == 2).all() and (np.sort(blocks[:, 1:3], axis=1) == [0, 1]).all()


def test_block_culling_needs_tile_culling_and_follows_the_measured_choice(room):
    from rayvr.frame.passes.primary_rays import measured_choice

    rig = camera_rig(room, Pinhole(), None)
    room.settings = RenderSettings(primary="rays", tile_culling=False, block_culling=True)
    with pytest.raises(ValueError, match="tile culling"):
        room.render(rig)
    assert primary_rays.culls_tiles(RenderSettings(primary="rays", block_culling=True))   # the blocks imply the cull
    for n in (1, 16):
        room.settings = RenderSettings(primary="rays", msaa=n)
        assert room.plan().block_culling == measured_choice("pinhole", n)["block_culling"]
        room.settings = RenderSettings(primary="rays", msaa=n, block_culling=False)
        assert room.plan().tile_culling and not room.plan().block_culling   # an explicit value wins
    room.settings = RenderSettings()


@pytest.mark.parametrize("culling", [dict(tile_culling=True, block_culling=False), dict(block_culling=True),
                                     dict(block_culling=True, tile_lists=64)], ids=["tiles", "blocks", "blocks and lists"])
def test_a_scene_whose_bvh_is_one_leaf_cuts_to_that_leaf_alone(gl, culling):
    """A BVH of one leaf (a scene of up to 8 triangles) is packed as a root whose right child is an
    empty slot: an inverted box (rayvr/accel/bvh.py EMPTY_LO > EMPTY_HI) with count 0, which reads as
    an internal node pointing back at the root. The cuts must never keep it: its box overflowed the
    frustum test to 'meets every frustum', so a tile that missed the leaf opened it forever (Mesa
    stops a loop after 65535 sweeps; the H200 hung). Every tile and block list holds the leaf (entry
    0) or nothing, and the frame is the per-ray one."""
    from rayvr.frame.cameras.rig import Pose, StereoRig
    from rayvr.renderer import Renderer
    from rayvr.scene.loader import from_arrays

    tri = from_arrays(np.array([[-0.2, -0.2, -3.0], [0.2, -0.2, -3.0], [0.0, 0.2, -3.0]]), np.array([[0, 1, 2]]),
                      name="one triangle")
    rig = StereoRig(Pose(), ipd=0.064, fov_y=60.0, size=(64, 32))
    with Renderer(tri, gl=gl) as r:
        ref = render(r, rig, 1, tile_culling=False)
        got = render(r, rig, 1, **culling)
        nx, ny = tile_grid(*rig.size)
        tiles = words(r, "tile_entries", nx * ny * 2, TILE_ENTRIES + 1)
        lists = [tiles] + ([words(r, "block_entries", 2, TILE_ENTRIES + 1)] if culling.get("block_culling") else [])
    assert np.array_equal(ref[0], got[0]) and np.array_equal(ref[1], got[1]) and (ref[0] != NO_HIT).any()
    assert (tiles[:, 0] == 0).any()   # tiles that miss the leaf have nothing to walk
    for words_ in lists:
        counts = words_[:, 0]
        assert counts.max() == 1 and (words_[:, 1][counts == 1] == 0).all(), counts  # the leaf, never the empty slot
