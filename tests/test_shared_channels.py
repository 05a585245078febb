"""Shared channel shading (RenderSettings.share_channel_shading, frame/passes/primary_rays.py
shares_channels): a chromatic camera's three colour channel sets cast together as sub-rays of each
sample, a pixel shaded once per distinct triangle they hit, at the first set's ray on it (green's
first), every channel taking its own share. Checked against a numpy composite of frames that cast
one set's rays for all three, against the frame that shades every set apart, and across culling."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.scene.surfaces import surface_groups
from rayvr.frame.cameras import Distorted, Pinhole
from rayvr.frame.graph import SHARED_CHANNEL
from rayvr.frame.passes import primary_rays
from rayvr.frame.cameras.rig import StereoRig
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import MaterialConfig

SIZE = (96, 64)
CHROMATIC = Distorted()


@pytest.fixture(scope="module")
def room(gl):
    with Renderer(None, gl=gl) as r:
        yield r


def frame(r, camera, share=True, **settings):
    """(8-bit colour of both eyes, triangle IDs of both eyes)."""
    r.settings = RenderSettings(primary="rays", share_channel_shading=share, **settings)
    f = r.render(StereoRig.for_scene(r.scene, size=SIZE, camera=camera), aux=("triangle",))
    return np.stack([f.left.color, f.right.color]).astype(int), np.stack([f.left.aux["triangle"], f.right.aux["triangle"]])


# The order of the colour channel sets' sub-rays (glsl/common/camera.glsl): green's block, then blue's, red's.
BLOCKS = [(b + SHARED_CHANNEL) % 3 for b in range(3)]


def expected_shared(room, camera):
    """The shared frame from frames that cast one channel set's rays for all three (each channel c's
    triangles and its shading at c's rays): a pixel's distinct triangles are shaded once, each at
    the ray of the first set (in BLOCKS order) that hits it, and channel c takes the shading of its
    own triangle."""
    per_set = {c: frame(room, Distorted(coefficients=camera.coefficients[c]), share=False) for c in range(3)}
    colour = np.zeros_like(per_set[0][0])
    for c in range(3):
        rep = np.full(per_set[c][1].shape, -1)
        for b in reversed(BLOCKS):   # the first set in block order that hits c's triangle wins
            rep = np.where(per_set[b][1] == per_set[c][1], b, rep)
        for b in range(3):
            colour[..., c] = np.where(rep == b, per_set[b][0][..., c], colour[..., c])
    return colour, per_set


def test_each_distinct_triangle_of_a_pixel_is_shaded_once_for_the_channels_on_it(room):
    """One sub-ray per colour channel set, cast together: every channel shows the shading of the
    triangle its own ray hits, made at the first set's ray that hits it (green's where green's does):
    a numpy composite of three single-set frames; channels that hit other triangles than green's
    keep their own shading, as the frame that shades every set apart has it (merged by triangle, the
    default: by smooth surface a channel on the sphere's next triangle takes the first set's shading)."""
    shared, tri = frame(room, CHROMATIC)
    assert room.plan(camera=CHROMATIC).share_channels
    expected, per_set = expected_shared(room, CHROMATIC)
    assert np.array_equal(shared, expected)
    apart, _ = frame(room, CHROMATIC, share=False)
    for c in (0, 2):
        own = per_set[c][1] != per_set[SHARED_CHANNEL][1]   # hits another triangle than green's ray
        assert 0.0 < own.mean() < 0.1, (c, own.mean())        # most channels share; the edges do not
        first = own & ((per_set[c][1] != per_set[BLOCKS[1]][1]) | (BLOCKS[1] == c))   # no earlier set on it
        assert np.array_equal(shared[..., c][first], apart[..., c][first])
    assert np.array_equal(tri, per_set[SHARED_CHANNEL][1]) or (tri != per_set[SHARED_CHANNEL][1]).mean() < 0.1
    assert not np.array_equal(shared, apart)   # the approximation shows somewhere


@pytest.mark.parametrize("n, merge", [(4, "triangle"), (4, "surface"), (16, "triangle")])
def test_shared_msaa_lists_merge_every_sets_sub_rays(room, n, merge):
    """MSAA with the three sets cast together (4x: 12 sub-rays a pixel, green's block first; 16x: 48,
    masks of two words): the trace's lists against passes/primary_rays.msaa_lists over numpy traces
    of each set's own sub-rays, with each set's covered count in the meta; one round sequence for the
    frame, not three. By smooth surface (shading_merge "surface") numpy merges by scene/surfaces.py's."""
    from rayvr.accel.bvh import build_bvh, trace_reference
    from rayvr.frame.cameras.sampling import subsamples

    w, h = (30, 22) if n == 4 else (18, 14)
    rig = StereoRig.for_scene(room.scene, size=(w, h), camera=CHROMATIC)
    room.settings = RenderSettings(primary="rays", msaa=n, share_channel_shading=True,   # (16x: not by default)
                                   shading_merge=merge)
    fc = room.record(rig)
    room.gl.ctx.finish()
    plan = room.plan(camera=CHROMATIC)
    assert plan.share_channels and primary_rays.subrays(plan) == 3 * n and len(fc.channel_rounds) == 1
    slots = primary_rays.msaa_slots(plan)
    got = np.frombuffer(room.resource("msaa_hits").read(), np.uint32).reshape(slots, 2, h, w, 4)
    scene = room.scene
    bvh = build_bvh(scene.vertices, scene.indices)
    surfaces = surface_groups(scene.vertices, scene.indices, scene.triangle_material, scene.normals)
    offsets = np.tile(subsamples(n)[0], (3, 1))
    agree = []
    for e, eye in enumerate(rig.eyes()):
        tris, ts = [], []
        for b in BLOCKS:
            for i in range(n):   # numpy's traversal of set b's sub-ray i, GL rows (bottom-up) as the GPU's
                rays = CHROMATIC.rays(eye, b, (i, n))
                prim, t, _, _ = trace_reference(bvh, (rays.origins - scene.origin).reshape(-1, 3),
                                                rays.directions.reshape(-1, 3), tmin=rig.near)
                tris.append(np.asarray(prim, np.uint32).reshape(h, w)[::-1])
                ts.append(np.asarray(t, np.float32).reshape(h, w)[::-1])
        ref = primary_rays.msaa_lists(np.stack(tris, -1), np.stack(ts, -1), offsets, slots, channel_blocks=3,
                                      surfaces=surfaces if merge == "surface" else None)
        mine = got[:, e]
        count = (mine[0, ..., 2] >> 8) & 255
        used = np.arange(slots)[:, None, None] < count[None]
        agree.append((((mine[..., :2] == ref[..., :2]).all(-1) | ~used).all(0)
                      & (mine[0, ..., 2] >> 8 == ref[0, ..., 2] >> 8)))   # count and each set's covered
        assert count.max() >= 2
    assert np.mean(agree) >= 0.97, np.mean(agree)   # sub-rays grazing an edge may go either way


def test_shared_shading_costs_little_image_error(room):
    pytest.importorskip("flip_evaluator")
    from rayvr.quality.metrics import flip

    shared, _ = frame(room, CHROMATIC)
    apart, _ = frame(room, CHROMATIC, share=False)
    error = flip(apart[0] / 255.0, shared[0] / 255.0, float_encoding="srgb")
    assert 0.0 < error < 0.02, error   # at this size a channel's offset is a large part of a pixel


@pytest.mark.parametrize("culling", [dict(tile_culling=True), dict(tile_lists=64), dict(block_culling=True, tile_lists=64),
                                     dict(msaa=8, tile_lists=64), dict(msaa=16, tile_culling=True),
                                     dict(msaa=16, tile_lists=64)],
                         ids=["entries", "lists", "blocks and lists", "8x lists", "16x entries", "16x lists"])
def test_tile_culled_shared_frames_equal_the_per_ray_shared_frame(room, culling):
    """With tile culling the frame's one cull bounds all three channel sets' sub-rays, which the trace
    starts from (their entries, or the lists through tile_samples.comp, whose workgroup at 8x holds
    24 sub-rays a pixel, at 16x 48 with two-word masks): the frame per-ray traversal from the root gives."""
    shared, tri = frame(room, CHROMATIC, tile_culling=False, msaa=culling.get("msaa", 1))
    culled, culled_tri = frame(room, CHROMATIC, **culling)
    assert room.plan(camera=CHROMATIC).tile_culling and room.plan(camera=CHROMATIC).share_channels
    assert np.array_equal(tri, culled_tri) and np.array_equal(shared, culled)


def test_the_shared_cull_bounds_every_channel_sets_rays(room):
    """The frame's one cull (CULL_CHANNELS 3): every channel set's ray lies inside the planes the GPU
    wrote for its tile (one set's planes would leave the others' rays at the tiles' edges out)."""
    from test_tile_culling_frame import SHAPE, gl_tile_rays

    from rayvr.accel.frustum import tile_grid

    frame(room, CHROMATIC, tile_culling=True, **SHAPE)
    rig = StereoRig.for_scene(room.scene, size=SIZE, camera=CHROMATIC)
    nx, ny = tile_grid(*SIZE)
    planes = np.frombuffer(room.resource("tile_planes").read(), np.float32)[:2 * nx * ny * 20].reshape(-1, 5, 4)
    outside = 0.0
    for eye in range(2):
        for channel in range(3):
            for t, (o, d) in gl_tile_rays(room, rig, eye, channel, 1).items():
                pl = planes[eye * nx * ny + t].astype(np.float64)
                p = o + 3.0 * d
                side = p @ pl[:4, :3].T - pl[:4, 3] - 1e-5 * (1 + np.abs(p).sum(1, keepdims=True))
                outside = max(outside, side.max())
    assert outside <= 0.0, outside


def test_only_frames_it_serves_share(room):
    def shares(camera=CHROMATIC, **settings):
        room.settings = RenderSettings(primary="rays", **settings)
        return room.plan(camera=camera).share_channels

    assert shares() and not shares(share_channel_shading=False)
    assert not shares(camera=Pinhole())                 # one channel set
    assert shares(msaa=4) and shares(msaa=8)            # by default up to 8x, where it measured faster ...
    assert not shares(msaa=16) and shares(msaa=16, share_channel_shading=True)   # ... 16x only when asked:
    # 3 x 16 sub-rays fit a two-word coverage mask, 3 x 32 do not; SSAA shades every sub-ray
    assert not shares(msaa=32, share_channel_shading=True) and not shares(msaa=4, ssaa=True)
    assert shares(tile_culling=True) and shares(tile_lists=64)   # the one cull bounds every set's rays
    with Renderer(None, MaterialConfig(default="ssr"), gl=room.gl) as r:   # reads neighbours' G-buffer
        r.settings = RenderSettings(primary="rays")
        # ... through the pinhole's quadtree, which a distorted camera has none of: refused outright
        with pytest.raises(ValueError, match="screen-space tracing .ssr. marches the pinhole's depth buffer"):
            r.plan(camera=CHROMATIC)


def test_the_flags_turn_it_off_and_on():
    from rayvr.cli import build_parser

    parse = build_parser().parse_args
    assert parse(["capture", "--no-share-channel-shading"]).share_channel_shading is False
    assert parse(["capture", "--share-channel-shading"]).share_channel_shading is True
    assert parse(["capture"]).share_channel_shading is None   # unset: the config's, else auto (up to 8x)
