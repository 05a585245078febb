"""Frames too large for the device render in tiles (llvmpipe rendered 2x8192x8192 all black with
exit 0: its position channel is exactly 2 GiB), and frames too large even for that are refused
before anything is allocated, naming what does not fit."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import run_rayvr
from rayvr.frame.cameras.rig import StereoRig
from rayvr.frame.graph import (RESOURCE_BYTES_LIMIT, DeviceLimits, FrameTooLarge, Sizing, check_fits, compile_graph,
                         limit_problems)
from rayvr.scene.materials import parse_config
from rayvr.renderer import Renderer, candidate_passes
from rayvr.scene.loader import load


def _graph(gl, config=None):
    with Renderer(load(), parse_config(config or {}, "<t>"), gl=gl) as r:
        plan = r.plan()
        return compile_graph(candidate_passes(plan), plan), r.scene, tuple(r.assignments)


def test_resource_over_2_gib_is_refused_with_the_largest_size_that_fits(gl):
    graph, scene, assigned = _graph(gl)
    limits = DeviceLimits(max_texture_size=32768, max_ssbo_bytes=1 << 31, memory_bytes=None)
    big = Sizing((8192, 8192), 2, scene, assigned)
    assert any("position needs 2.00 GiB" in p for p in limit_problems(graph, big, limits))
    with pytest.raises(FrameTooLarge, match=r"largest size of this aspect that fits is (\d+)x\1") as e:
        check_fits(graph, big, limits)
    side = int(str(e.value).rsplit(" ", 1)[1].split("x")[0])
    # The position channel (rgba32f, 2 layers) is the largest: 32 B a pixel pair.
    assert side * side * 32 <= RESOURCE_BYTES_LIMIT < (side + 2) ** 2 * 32
    check_fits(graph, Sizing((side, side), 2, scene, assigned), limits)  # that size passes


def test_texture_side_storage_buffer_and_memory_limits(gl):
    graph, scene, assigned = _graph(gl, {"default": "shadows"})
    limits = DeviceLimits(max_texture_size=4096, max_ssbo_bytes=64 << 20, memory_bytes=256 << 20)
    wide = limit_problems(graph, Sizing((5000, 100), 2, scene, assigned), limits)
    assert any("at most 4096 pixels a side" in p for p in wide)
    lists = limit_problems(graph, Sizing((3000, 3000), 2, scene, assigned), limits)
    assert any(p.startswith("rt_lists needs") and "storage buffer" in p for p in lists)
    assert any("device memory" in p for p in lists)
    assert not limit_problems(graph, Sizing((64, 48), 2, scene, assigned), limits)


def test_capture_of_an_absurd_size_is_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "o"
    run = run_rayvr("capture", "--size", "100000x100000", "--out", out, timeout=120)
    assert run.returncode == 2
    lines = [line for line in run.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "size" in lines[0] and "Traceback" not in run.stderr, run.stderr
    assert not out.exists()


def test_frames_too_large_even_for_tiles_are_refused_naming_why(gl):

    with Renderer(load(), gl=gl) as r:
        with pytest.raises(FrameTooLarge, match="GiB of host memory"):
            r.tiles(StereoRig.for_scene(r.scene, size=(60000, 60000)))
        r.graph.limits = DeviceLimits(max_texture_size=4, max_ssbo_bytes=1 << 31, memory_bytes=None)
        with pytest.raises(FrameTooLarge, match="at most 4 pixels a side"):  # would take > MAX_TILES tiles
            r.tiles(StereoRig.for_scene(r.scene, size=(640, 480)))


def test_a_frame_too_large_for_the_device_renders_in_tiles_that_match_the_whole(gl):
    """With the device's limits made small, the frame is split into off-axis tiles whose pixels are
    the same rays: colour, depth and aux channels match the frame rendered whole (exactly but for
    rounding without sampled effects; with soft shadows a few points on a seed cell's boundary draw
    other samples, as between the two eyes)."""

    scene = load()
    rig = StereoRig.for_scene(scene, size=(61, 45), convergence=2.0)
    for config, noisy in (({"materials": {"mirror*": "reflections"}}, False), ({"default": "shadows"}, True)):
        with Renderer(scene, parse_config(config, "<t>"), gl=gl) as r:
            whole = r.render(rig, aux=("triangle", "normal"))
            r.graph.limits = DeviceLimits(max_texture_size=32, max_ssbo_bytes=1 << 31, memory_bytes=None)
            tiles = r.tiles(rig)
            assert len(tiles) == 4 and {t[2] - t[0] for t in tiles} == {30, 31}
            tiled = r.render(rig, aux=("triangle", "normal"))
        assert set(tiled.timings) <= set(tiled.passes)
        for eye in ("left", "right"):
            a, b = whole[eye], tiled[eye]
            same_tri = a.aux["triangle"] == b.aux["triangle"]
            assert same_tri.mean() > 0.995  # edge pixels may tie between two triangles
            off = np.abs(a.color.astype(int) - b.color.astype(int)).max(-1)[same_tri]
            assert (off > 2).mean() < (0.03 if noisy else 1e-9), (config, (off > 2).mean())
            assert np.allclose(a.depth[same_tri], b.depth[same_tri], rtol=1e-5)
            assert np.allclose(a.aux["normal"][same_tri], b.aux["normal"][same_tri], atol=2e-3)
