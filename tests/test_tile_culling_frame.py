"""Tile frustum culling in the frame's primary rays (RenderSettings.tile_culling, frame/passes/primary_rays.py,
glsl/accel/tile_cull.comp with TILE_CAMERA) against per-ray traversal from the root, the reference."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.frame.passes import primary_rays
from conftest import camera_rig
from PIL import Image

from rayvr.accel.frustum import tile_grid
from rayvr.frame.cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from rayvr.frame.cameras.sampling import subsamples
from rayvr.gl.gpu_layout import BLOCK_TILES, NO_HIT, TILE_ENTRIES, TILE_PIXELS
from rayvr.renderer import RenderSettings

SIZE = (48, 24)   # 3 x 3 tiles an eye
# The tile shapes these tests' numpy readings of the GPU's buffers assume, set rather than left to the
# measured choice (which may pick others; tests/test_tile_shapes.py renders every shape).
SHAPE = dict(tile_size="x".join(map(str, TILE_PIXELS)), tile_entries=TILE_ENTRIES, block_tiles=BLOCK_TILES[0])

# name -> (camera model, sub-rays per sample, vertical fov or None)
CASES = {
    "pinhole 1x": (Pinhole(), 1, None),
    "pinhole 4x msaa": (Pinhole(), 4, None),
    "dof 4x": (ThinLens(aperture=0.08, focus=1.5), 4, None),
    "distorted chromatic": (Distorted(), 1, None),
    "foveated": (Foveated(), 1, None),
    "wide 210x130": (Wide(fov_x=210.0), 1, 130.0),
}


def render(r, rig, samples, culled):
    """(triangle IDs of both eyes, colour of both eyes, the frame's tile lists or None)."""
    # share_channel_shading off: every channel set culled and cast on its own (tests/test_shared_channels.py has it on)
    r.settings = RenderSettings(primary="rays", msaa=samples, tile_culling=culled, share_channel_shading=False, **SHAPE)
    f = r.render(rig, aux=("triangle",))
    lists = None
    if culled:
        nx, ny = tile_grid(*rig.size)
        words = np.frombuffer(r.resource("tile_entries").read(), np.uint32)[:nx * ny * 2 * (TILE_ENTRIES + 1)]
        planes = np.frombuffer(r.resource("tile_planes").read(), np.float32)[:nx * ny * 2 * 20].reshape(-1, 5, 4)
        lists = words.reshape(-1, TILE_ENTRIES + 1), planes
    tri = np.stack([f.left.aux["triangle"], f.right.aux["triangle"]])
    return tri, np.stack([f.left.color, f.right.color]), lists


@pytest.mark.parametrize("case", list(CASES))
def test_tile_culled_frame_equals_per_ray(room, case):
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov)
    tri, color, _ = render(room, rig, samples, False)
    tri_c, color_c, (lists, planes) = render(room, rig, samples, True)
    assert (tri != NO_HIT).mean() > 0.5
    assert np.array_equal(tri, tri_c), f"{case}: {np.mean(tri != tri_c):.2%} of pixels differ"
    assert np.array_equal(color, color_c)   # every round's sub-rays (MSAA slots, channels) agree
    # culling took place: some tile lists entries below the root's children, not the fallback
    culled = (lists[:, 0] > 0) & ~((lists[:, 0] == 2) & (np.sort(lists[:, 1:3], axis=1) == [0, 1]).all(1))
    assert culled.any(), f"{case}: every tile fell back to the root"
    assert not (planes[culled, :, 3] == 1.0).all(axis=1).any()


def test_tiles_too_wide_fall_back_to_the_root(room):
    """A 210-degree view at 16 x 8 pixels is one tile an eye, its rays over more than a half-space:
    its list is the root's children and the hits are still per-ray traversal's."""
    rig = camera_rig(room, Wide(fov_x=210.0), 130.0, size=TILE_PIXELS)
    tri, _, _ = render(room, rig, 1, False)
    tri_c, _, (lists, planes) = render(room, rig, 1, True)
    assert np.array_equal(tri, tri_c) and (tri != NO_HIT).any()
    assert (lists[:, 0] == 2).all() and (np.sort(lists[:, 1:3], axis=1) == [0, 1]).all()
    assert (planes == [0, 0, 0, 1]).all()   # the fallback's mark (tile_cull.comp)


def gl_tile_rays(r, rig, eye, channel, samples, tile=TILE_PIXELS):
    """Every sub-ray of `eye` (numpy reference, scene-local origins) grouped by frame `tile` (w, h):
    {tile index within the eye: (origins (k, 3), directions (k, 3))}."""
    view = rig.eyes()[eye]
    w, h = view.size
    offsets = subsamples(samples)[0]
    out = {}
    for i in range(samples):
        rays = rig.camera.rays(view, channel, subsample=(i, samples) if samples > 1 else None)
        rows = np.arange(h)[:, None].repeat(w, 1)
        gl_y, x = h - 1 - rows, np.arange(w)[None, :].repeat(h, 0)
        nx, _ = tile_grid(w, h, tile)
        index = (gl_y // tile[1]) * nx + x // tile[0]
        ok = rays.valid
        o = (rays.origins - r.scene.origin)[ok]
        for t in np.unique(index[ok]):
            m = index[ok] == t
            prev = out.get(int(t), (np.zeros((0, 3)), np.zeros((0, 3))))
            out[int(t)] = (np.r_[prev[0], o[m]], np.r_[prev[1], rays.directions[ok][m]])
    assert len(offsets) == samples
    return out


@pytest.mark.parametrize("case", ["dof 4x", "distorted chromatic", "foveated"])
def test_every_sub_ray_lies_inside_its_tile_planes(room, case):
    """The planes the GPU wrote for each tile hold every point o + t d of every sub-ray of its pixels
    (footprint offsets, lens points; the last channel set culled: green, channel_order)."""
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov)
    _, _, (lists, planes) = render(room, rig, samples, True)
    nx, ny = tile_grid(*SIZE)
    channel = 1 if camera.channels == 3 else 0
    checked = 0
    for eye in range(2):
        for t, (o, d) in gl_tile_rays(room, rig, eye, channel, samples).items():
            pl = planes[eye * nx * ny + t].astype(np.float64)
            assert lists[eye * nx * ny + t, 0] > 0
            for s in (0.0, 0.5, 3.0, 50.0):
                p = o + s * d
                side = p @ pl[:4, :3].T - pl[:4, 3]
                scale = 1e-5 * (1 + np.abs(p).sum(1, keepdims=True))
                assert (side <= scale).all(), (case, eye, t, side.max())
            checked += len(o)
    assert checked >= 2 * SIZE[0] * SIZE[1] * samples * (0.2 if camera.sparse else 1.0)


def test_capture_with_tile_culling_writes_the_same_frame(tmp_path):
    from test_cli import rayvr

    outs = []
    for flags in (("--no-tile-culling",), ("--tile-culling",)):
        out = tmp_path / flags[0]
        run = rayvr("capture", "--size", "32x16", "--out", str(out), "--msaa", "4", *flags, "--timings")
        assert run.returncode == 0, run.stderr
        assert ("tile_entries" in run.stdout or "primary_rays" in run.stdout)
        outs.append(np.asarray(Image.open(out / "frame_left.png")))
    assert outs[0].std() > 0 and np.array_equal(outs[0], outs[1])


def test_bench_primary_rows_with_and_without_frame_tile_culling(tmp_path):
    from conftest import quick_bench

    result = quick_bench("primary", tmp_path, "--configs", "raster_gbuffer,pinhole", "--counts", "1", "--tile-culling")
    rows = [(r["config"], r["tile_culling"]) for r in result["rows"]]
    assert rows == [("raster_gbuffer", False), ("pinhole", False), ("pinhole", True)]
    plain, culled = result["rows"][1], result["rows"][2]
    assert culled["cull_ms"] >= 0 and plain["cull_ms"] == 0 and culled["primary_ms"] >= culled["cull_ms"]
    # the standalone central rays' GPU-counted work: front to back does no more than tree order
    assert plain["tiles_agree"] == 1.0
    assert plain["tiles_entry_tests"] <= plain["tree_entry_tests"] and "trace_entry_tests" not in plain
    assert plain["tiles_triangle_tests"] <= plain["tree_triangle_tests"] + 1e-9
    keys = " ".join(result["meta"]["targets"])
    assert "[tile culling]" in keys and "[per ray]" in keys


def test_tile_culling_is_chosen_where_it_measured_faster():
    """Default (None): the measured choice of the camera model and sub-ray count
    (rayvr/assets/primary_visibility.json: on the H200 culled tiles won for every model but the
    foveated one, whose sparse samples fill its tiles partly); explicit values win; anything else is
    refused."""
    from rayvr.frame.passes.primary_rays import measured_choice

    for model in ("pinhole", "distorted", "foveated", "dof", "wide"):
        for n in (1, 4, 16):
            want = measured_choice(model, n)["tile_culling"]
            assert primary_rays.culls_tiles(RenderSettings(primary="rays", msaa=n), model) == want, (model, n)
    assert primary_rays.culls_tiles(RenderSettings(msaa=4)) and not primary_rays.culls_tiles(RenderSettings(msaa=4), "foveated")
    assert primary_rays.culls_tiles(RenderSettings(primary="rays", tile_culling=True), "foveated")
    assert not primary_rays.culls_tiles(RenderSettings(msaa=4, tile_culling=False))
    with pytest.raises(ValueError, match="tile_culling"):
        RenderSettings(tile_culling="yes")


def test_the_frame_plan_follows_the_automatic_choice(room):
    r = room
    try:
        r.settings = RenderSettings(msaa=4)
        assert r.plan().tile_culling and r.plan(camera=Distorted()).tile_culling
        assert r.plan(camera=ThinLens(aperture=0.05)).tile_culling
        assert not r.plan(camera=Foveated()).tile_culling
        r.settings = RenderSettings(primary="rays", tile_culling=False)
        assert not r.plan().tile_culling
    finally:
        r.settings = RenderSettings()


@pytest.mark.parametrize("case", ["pinhole 1x", "pinhole 4x msaa"])
def test_planar_tile_beams_hold_every_sub_ray_and_touch_the_outer_ones(room, case):
    """A planar camera's block-culled tile frusta come from each tile's four corner rays
    (accel/tile_beams_planar.comp) instead of a reduction over its rays: they must still hold every
    point o + t d of every sub-ray, and be as tight as the rays allow: each side plane touched by a
    ray of the tile (its normal's angle to the nearest ray under 1e-3), as the corner rays are rays."""
    camera, samples, fov = CASES[case]
    rig = camera_rig(room, camera, fov)
    room.settings = RenderSettings(primary="rays", msaa=samples, block_culling=True, **SHAPE)
    room.render(rig)
    assert {p.name: p for p in room.compiled().passes}["primary_rays"].planar
    nx, ny = tile_grid(*SIZE)
    planes = np.frombuffer(room.resource("tile_planes").read(), np.float32)[:nx * ny * 2 * 20].reshape(-1, 5, 4)
    checked = 0
    for eye in range(2):
        for t, (o, d) in gl_tile_rays(room, rig, eye, 0, samples).items():
            pl = planes[eye * nx * ny + t].astype(np.float64)
            assert not np.array_equal(pl[4], [0.0, 0.0, 0.0, 1.0])   # culled
            for s in (0.0, 0.5, 3.0, 50.0):
                p = o + s * d
                side = p @ pl[:4, :3].T - pl[:4, 3]
                assert (side <= 1e-5 * (1 + np.abs(p).sum(1, keepdims=True))).all(), (case, eye, t, side.max())
            unit = d / np.linalg.norm(d, axis=1, keepdims=True)
            closest = (unit @ pl[:4, :3].T / np.linalg.norm(pl[:4, :3], axis=1)).max(0)
            assert (closest > -1e-3).all(), (case, eye, t, closest)
            checked += len(o)
    assert checked == 2 * SIZE[0] * SIZE[1] * samples
