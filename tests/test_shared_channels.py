"""Shared channel shading (RenderSettings.share_channel_shading, frame/passes/primary_rays.py
shares_channels): a chromatic camera's red and blue rays that hit the triangle of the pixel's green
ray take green's shading; where they hit another, they are shaded on their own. Checked against
the frame that shades every channel (the reference) and against a camera that casts green's rays
for all three channels."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.frame.cameras import Distorted, Pinhole
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
    """(8-bit colour of both eyes, the channel_match bits of both eyes (rows top-down) or None)."""
    r.settings = RenderSettings(primary="rays", share_channel_shading=share, **settings)
    f = r.render(StereoRig.for_scene(r.scene, size=SIZE, camera=camera))
    match = None
    if r.plan(camera=camera).share_channels:
        w, h = SIZE
        match = np.frombuffer(r.resource("channel_match").read(), np.uint32).reshape(2, h, w)[:, ::-1]
    return np.stack([f.left.color, f.right.color]).astype(int), match


def test_channels_that_hit_greens_triangle_take_its_shading(room):
    shared, match = frame(room, CHROMATIC)
    apart, _ = frame(room, CHROMATIC, share=False)
    greens, _ = frame(room, Distorted(coefficients=CHROMATIC.coefficients[1]))  # green's rays for every channel
    assert np.array_equal(shared[..., 1], apart[..., 1])   # green's round is unchanged
    for k in (0, 2):
        same = (match >> k & 1).astype(bool)
        assert 0.9 < same.mean() < 1.0, (k, same.mean())   # most channels share; the edges do not
        assert np.array_equal(shared[..., k][~same], apart[..., k][~same])  # shaded apart: the reference's
        assert np.array_equal(shared[..., k][same], greens[..., k][same])   # shared: green's shading
    assert not np.array_equal(shared, apart)   # the approximation shows somewhere


def test_shared_shading_costs_little_image_error(room):
    pytest.importorskip("flip_evaluator")
    from rayvr.quality.metrics import flip

    shared, _ = frame(room, CHROMATIC)
    apart, _ = frame(room, CHROMATIC, share=False)
    error = flip(apart[0] / 255.0, shared[0] / 255.0, float_encoding="srgb")
    assert 0.0 < error < 0.02, error   # at this size a channel's offset is a large part of a pixel


@pytest.mark.parametrize("culling", [dict(tile_culling=True), dict(tile_lists=64), dict(block_culling=True, tile_lists=64)],
                         ids=["entries", "lists", "blocks and lists"])
def test_tile_culled_shared_frames_equal_the_per_ray_shared_frame(room, culling):
    """With tile culling the frame's one cull bounds all three channel sets' rays, which the probe,
    red's and blue's casts start from (their entries, or the lists through tile_samples.comp): the
    same frame and the same channel matches as per-ray traversal from the root."""
    shared, match = frame(room, CHROMATIC, tile_culling=False)
    culled, culled_match = frame(room, CHROMATIC, **culling)
    assert room.plan(camera=CHROMATIC).tile_culling and room.plan(camera=CHROMATIC).share_channels
    assert 0.9 < (match & 1).astype(bool).mean() < 1.0
    assert np.array_equal(match, culled_match) and np.array_equal(shared, culled)


def test_the_shared_cull_bounds_every_channel_sets_rays(room):
    """The frame's one cull (CULL_CHANNELS 3): every channel set's ray lies inside the planes the GPU
    wrote for its tile (one set's planes would leave the others' rays at the tiles' edges out)."""
    from test_tile_culling_frame import gl_tile_rays

    from rayvr.accel.frustum import tile_grid

    frame(room, CHROMATIC, tile_culling=True)
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
    assert not shares(msaa=4)                           # MSAA rounds are per slot (not shared yet)
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
    assert parse(["capture"]).share_channel_shading is None   # unset: the config's, else on
