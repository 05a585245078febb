"""Tile triangle lists (RenderSettings.tile_lists; glsl/accel/tile_tris.comp builds them,
glsl/rt/tile_samples.comp tests the sub-rays against them) against per-ray traversal from the BVH
root, the reference:
the same triangle, distance and colour on every sub-ray of every camera model, with lists that
overflow too; and each list checked against a numpy reading of what it must hold."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.frame.passes import primary_rays
from conftest import camera_rig

from rayvr.accel.frustum import tile_grid
from rayvr.frame.cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from rayvr.frame.passes.primary_rays import TILE_OVERFLOW
from rayvr.gl.gpu_layout import NO_HIT, TILE_PIXELS
from rayvr.renderer import RenderSettings
from test_tile_culling_frame import SHAPE

SIZE = (48, 24)   # 3 x 3 tiles an eye

# name -> (camera model, sub-rays per sample, vertical fov or None)
CASES = {
    "pinhole 1x": (Pinhole(), 1, None),
    "pinhole 16x msaa": (Pinhole(), 16, None),
    "pinhole 32x msaa": (Pinhole(), 32, None),   # the per-pixel trace's smaller block (8x4)
    "distorted chromatic 4x": (Distorted(), 4, None),
    "foveated": (Foveated(), 1, None),
    "wide 210x130": (Wide(fov_x=210.0), 1, 130.0),
    "dof 4x at 0.5": (ThinLens(aperture=0.08, focus=0.5), 4, None),
    "dof 4x at 1.5": (ThinLens(aperture=0.08, focus=1.5), 4, None),
    "dof 4x at 6": (ThinLens(aperture=0.08, focus=6.0), 4, None),
}


def render(r, rig, samples, lists, ssaa=False, merge="triangle"):
    """(triangle IDs, depth, colour of both eyes, the frame's list words (tiles, bound + 1, 2) or None)."""
    kw = dict(tile_culling=True, tile_lists=lists, **SHAPE) if lists else dict(tile_culling=False)
    r.settings = RenderSettings(primary="rays", msaa=samples, ssaa=ssaa, shading_merge=merge, **kw)
    f = r.render(rig, aux=("triangle",))
    words = None
    if lists:
        nx, ny = tile_grid(*rig.size)
        words = np.frombuffer(r.resource("tile_tris").read(), np.uint32)[:nx * ny * 2 * (lists + 1) * 2]
        words = words.reshape(nx * ny * 2, lists + 1, 2)
    both = lambda a, b: np.stack([a, b])
    return (both(f.left.aux["triangle"], f.right.aux["triangle"]), both(f.left.depth, f.right.depth),
            both(f.left.color, f.right.color), words)


@pytest.mark.parametrize("case", list(CASES))
def test_tile_lists_give_the_per_ray_frame(room, case):
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov)
    tri, depth, color, _ = render(room, rig, samples, 0)
    tri_l, depth_l, color_l, words = render(room, rig, samples, 256)
    assert (tri != NO_HIT).mean() > 0.5
    assert np.array_equal(tri, tri_l), f"{case}: {np.mean(tri != tri_l):.2%} of pixels differ"
    assert np.array_equal(depth, depth_l) and np.array_equal(color, color_l)  # every round's sub-rays agree
    counts = words[:, 0, 0]
    listed = (counts > 0) & (counts != TILE_OVERFLOW)
    assert listed.mean() >= 0.3, f"{case}: tiles should be cast from their lists, counts {counts}"


@pytest.mark.parametrize("case", ["pinhole 16x msaa", "distorted chromatic 4x"])
def test_tile_lists_merge_by_surface_as_the_per_ray_trace_does(room, case):
    """shading_merge "surface": tile_samples.comp's sequential merge of a listed tile's pixels and
    primary.comp's parallel one give the same frame, and it differs from the merge by triangle."""
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov)
    tri, depth, color, _ = render(room, rig, samples, 0, merge="surface")
    tri_l, depth_l, color_l, words = render(room, rig, samples, 256, merge="surface")
    assert np.array_equal(tri, tri_l) and np.array_equal(depth, depth_l) and np.array_equal(color, color_l)
    counts = words[:, 0, 0]
    assert ((counts > 0) & (counts != TILE_OVERFLOW)).mean() >= 0.3  # most tiles cast from their lists
    _, _, by_triangle, _ = render(room, rig, samples, 256)
    assert not np.array_equal(color_l, by_triangle)  # the sphere's triangles in a pixel merged


@pytest.mark.parametrize("case", ["pinhole 16x msaa", "distorted chromatic 4x", "dof 4x at 0.5"])
def test_every_sub_ray_gets_the_per_ray_triangle_and_distance(room, case):
    """The MSAA trace's per-pixel lists (msaa_hits: each distinct triangle with the mask of the sub-rays
    on it and its representative sub-ray's distance) from tile_samples.comp equal per-ray traversal's
    entry for entry: every sub-ray hit the same triangle, the representatives at the same distance."""
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov)
    lists = []
    for bound in (0, 256):
        render(room, rig, samples, bound)
        hits = np.frombuffer(room.resource("msaa_hits").read(), np.uint32).reshape(-1, 2 * SIZE[0] * SIZE[1], 4)
        lists.append(hits)
    ref, got = lists
    n = (ref[0, :, 2] >> 8) & 255
    assert np.array_equal(n, (got[0, :, 2] >> 8) & 255) and n.max() >= 2
    for slot in range(int(n.max())):
        defined = n > slot
        assert np.array_equal(ref[slot][defined], got[slot][defined]), (case, slot)


def test_tile_lists_agree_with_embree(room):
    """The triangle each 1x sample of a pinhole and a 210-degree camera sees through the tile lists
    (and the block culling) is the one Embree finds along the model's numpy rays (a ray through an
    edge two triangles share may go to either)."""
    from test_raytrace import embree

    scene = room.scene
    es = embree(scene.vertices, scene.indices)
    for camera, fov in ((Pinhole(), None), (Wide(fov_x=210.0), 130.0)):
        rig = camera_rig(room, camera, fov, size=(96, 48))
        room.settings = RenderSettings(primary="rays", tile_lists=256, block_culling=True)
        frame = room.render(rig, aux=("triangle",))
        for eye in rig.eyes():
            rays = eye.camera.rays(eye)
            ok = rays.valid.reshape(-1)
            o = (rays.origins - scene.origin + rig.near * rays.directions).reshape(-1, 3).astype(np.float32)
            d = rays.directions.reshape(-1, 3).astype(np.float32)
            hit = es.run(np.ascontiguousarray(o[ok]), np.ascontiguousarray(d[ok]), output=1)
            expected = np.where(hit["primID"] >= 0, hit["primID"].astype(np.int64), NO_HIT).astype(np.uint32)
            triangle = frame.eyes[eye.name].aux["triangle"].reshape(-1)[ok]
            assert (triangle == expected).mean() >= 0.999, (camera.name, eye.name, (triangle != expected).sum())


def test_ssaa_rounds_cast_from_the_lists_too(room):
    rig = camera_rig(room, Pinhole(), None)
    assert np.array_equal(render(room, rig, 4, 0, ssaa=True)[2], render(room, rig, 4, 64, ssaa=True)[2])


def test_lists_that_overflow_change_nothing(room):
    """A bound of 16 triangles overflows the busier tiles, whose rays then walk from their entries."""
    rig = camera_rig(room, Pinhole(), None)
    tri, depth, color, _ = render(room, rig, 4, 0)
    tri_l, depth_l, color_l, words = render(room, rig, 4, 16)
    counts = words[:, 0, 0]
    assert (counts == TILE_OVERFLOW).any() and ((counts > 0) & (counts != TILE_OVERFLOW)).any(), counts
    assert np.array_equal(tri, tri_l) and np.array_equal(depth, depth_l) and np.array_equal(color, color_l)


def test_a_tile_too_wide_to_cull_has_no_list(room):
    """A 210-degree view at 16 x 8 pixels: one tile an eye, not culled (tile_cull.comp's fallback),
    so no list: its rays walk the BVH."""
    rig = camera_rig(room, Wide(fov_x=210.0), 130.0, size=TILE_PIXELS)
    tri, _, _, _ = render(room, rig, 1, 0)
    tri_l, _, _, words = render(room, rig, 1, 256)
    assert (words[:, 0, 0] == TILE_OVERFLOW).all() and np.array_equal(tri, tri_l)


def test_each_list_holds_what_its_rays_hit_nearest_first(room):
    """Numpy reading of the GPU's lists: every triangle a ray of the tile hits (the per-ray frame's
    IDs) is listed; entries are distinct BVH slots sorted by key, and each key is at most the
    triangle's nearest vertex along the tile's central direction (its far plane's normal)."""
    rig = camera_rig(room, Pinhole(), None)
    tri, _, _, _ = render(room, rig, 1, 0)
    _, _, _, words = render(room, rig, 1, 256)
    planes = np.frombuffer(room.resource("tile_planes").read(), np.float32)[:len(words) * 20].reshape(-1, 5, 4)
    bvh = room.accel.gpu.bvh
    verts = bvh.triangles().astype(np.float64)
    nx, ny = tile_grid(*SIZE)
    w, h = SIZE
    checked = 0
    for eye in range(2):
        gl_ids = tri[eye][::-1]   # rows top-down -> GL rows (tiles count from the bottom)
        for ty in range(ny):
            for tx in range(nx):
                t = eye * nx * ny + ty * nx + tx
                n = words[t, 0, 0]
                if n == TILE_OVERFLOW:
                    continue
                slots, keys = words[t, 1:1 + n, 0], words[t, 1:1 + n, 1].view(np.float32)
                assert len(set(slots.tolist())) == n
                assert (np.diff(keys) >= 0).all()
                c = planes[t, 4, :3].astype(np.float64)
                assert (keys <= (verts[slots] @ c).min(1) + 1e-6).all()
                block = gl_ids[ty * TILE_PIXELS[1]:(ty + 1) * TILE_PIXELS[1], tx * TILE_PIXELS[0]:(tx + 1) * TILE_PIXELS[0]]
                hit = set(block[block != NO_HIT].tolist())
                assert hit <= set(bvh.prim_ids[slots].tolist()), (t, hit - set(bvh.prim_ids[slots].tolist()))
                checked += len(hit)
    assert checked > 20


def test_tile_lists_need_tile_culling(room):
    rig = camera_rig(room, Pinhole(), None)
    room.settings = RenderSettings(primary="rays", tile_culling=False, tile_lists=64)
    with pytest.raises(ValueError, match="tile culling"):
        room.render(rig)
    with pytest.raises(ValueError, match="tile list bound"):
        RenderSettings(tile_lists=100)
    assert primary_rays.culls_tiles(RenderSettings(primary="rays", tile_lists=64))   # the lists imply the cull


@pytest.mark.parametrize("samples", [1, 4, 8, 16, 32])
@pytest.mark.parametrize("sets", [1, 3], ids=["one set", "shared channel sets"])
def test_an_msaa_trace_block_lies_in_one_tile(samples, sets):
    """With tile lists the MSAA trace (rt/primary.comp) casts only the tiles whose list overflowed and
    leaves the others' workgroups whole, so no workgroup may span two tiles: its block of pixels
    divides the 16x8 tile, for every sub-ray count a sample casts (shared channel shading at 1x casts
    3, which once gave 4x5 blocks: frames that differed on the H200), and it keeps the pixels of one
    set's block with shared channel sets (full warps)."""
    from rayvr.frame.passes.primary_rays import MSAA_GROUP, msaa_block

    w, h = msaa_block(samples)
    assert TILE_PIXELS[0] % w == 0 and TILE_PIXELS[1] % h == 0, (samples, sets, w, h)
    # the most pixels whose sub-rays of one set fit (the group holds all sets': 192 invocations shared)
    assert w * h == 1 or (w * h * samples <= MSAA_GROUP < 2 * w * h * samples)
    assert (w * h * samples * sets) % 32 == 0   # full 32-lane warps, one set or three
