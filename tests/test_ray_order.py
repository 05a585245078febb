"""Ray reordering (--ray-order morton, frame/passes/ray_order.py) and persistent threads (--persistent
on, frame/passes/persistent_threads.py) in the wavefront of frame/passes/trace_effect.py: the keys
are octant + Morton code as numpy computes them, the sort is a stable permutation by key, and the
frames and the wavefront's hits with either option, or both, are exactly the default ones."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import camera_rig
from rayvr.frame.passes import ray_order
from rayvr.frame.passes.prefix_scan import dispatch_shape
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config

VARIANTS = [("morton", "off"), ("none", "on"), ("morton", "on")]
WAVE_PATH = np.dtype([("origin", "<f4", 4), ("direction", "<f4", 4), ("throughput", "<f4", 4),
                      ("radiance", "<f4", 4), ("hit", "<u4", 4)])  # glsl/rt/wave.glsl WavePath
SHADOW_SLOT = np.dtype([("origin", "<f4", 4), ("direction", "<f4", 4), ("light", "<f4", 4)])


def test_the_morton_code_interleaves_x_y_z_from_x_down():
    assert ray_order.spread_bits(np.array([0b101])).tolist() == [0b001000001]
    lo, scale = np.zeros(3, np.float32), np.ones(3, np.float32)
    # cell (1, 0, 0) -> x's bit 0 at bit 2; cell (0, 0, 3) -> z's bits at 0 and 3
    keys = ray_order.order_keys([[1.5, 0.2, 0.9], [0.1, 0.1, 3.2]], [[1, 1, 1], [1, 1, 1]], lo, scale)
    assert keys.tolist() == [0b100, 0b1001]
    # the octant: x < 0, y < 0, z < 0 from high to low, above the 21 Morton bits; -0.0 is not < 0
    octants = ray_order.order_keys(np.zeros((3, 3)), [[-1, 1, 1], [1, -1, -1], [-0.0, 1, 1]], lo, scale)
    assert (octants >> np.uint32(3 * ray_order.ORDER_AXIS_BITS)).tolist() == [0b100, 0b011, 0]
    # origins outside the bounds clamp to the edge cells
    edge = ray_order.order_keys([[-5, 500, 0]], [[1, 1, 1]], lo, scale)
    assert edge.tolist() == [int(ray_order.spread_bits(np.array([127]))[0]) << 1]


def test_order_bounds_cut_the_scene_into_cells_and_a_flat_axis_into_one():
    lo, scale = ray_order.order_bounds(np.array([[0, 0, 1], [4, 0, 3]], np.float32))
    assert lo.tolist() == [0, 0, 1] and scale.tolist() == [32.0, 0.0, 64.0]


def gpu_order(gl, rays: int, paths: np.ndarray, shadows: np.ndarray, count: int, capacity: int, items: int = 1):
    """The (key, ray) pairs ray_order.comp writes for the first `count` of `paths` / `shadows` and
    their sorted order (the count on the GPU, in wave_args[items]; 1 for paths)."""
    ctx = gl.ctx
    order = ray_order.RayOrder(ctx, {"RT_SLOT": 0})
    args = np.zeros((2, 4), np.uint32)
    args[:, 3] = count
    from rayvr.gl.gpu_layout import SSBO
    bufs = {"wave_paths": ctx.buffer(paths.tobytes()), "wave_shadows": ctx.buffer(shadows.tobytes()),
            "wave_args": ctx.buffer(args.tobytes())}
    for name, b in bufs.items():
        b.bind_to_storage_buffer(SSBO[name])
    untouched = np.full((capacity, 2), 0xABCDEF01, np.uint32)  # what entries past the count keep
    pairs, alt = (ctx.buffer(untouched.tobytes()) for _ in range(2))
    table = ctx.buffer(bytes(ray_order.sort_table_bytes(capacity)))
    vertices = np.array([[-1, -2, -3], [3, 2, 1]], np.float32)
    order.keys(order.programs[rays], vertices, pairs, capacity, wave_items=items)
    keys = np.frombuffer(pairs.read(), np.uint32).reshape(-1, 2).copy()
    out = order.sort(pairs, alt, table, capacity, bufs["wave_args"], items)
    sorted_pairs = np.frombuffer(out.read(), np.uint32).reshape(-1, 2).copy()
    for b in (*bufs.values(), pairs, alt, table):
        b.release()
    order.release()
    return keys, sorted_pairs, ray_order.order_bounds(vertices)


def random_rays(rng, n):
    o = rng.uniform(-2, 4, (n, 3)).astype(np.float32)  # partly outside the bounds
    d = rng.normal(size=(n, 3)).astype(np.float32)
    d[rng.random((n, 3)) < 0.05] = 0.0  # +0: not negative
    return o, d


def test_the_gpu_keys_are_numpys_and_the_order_a_stable_permutation_by_key(gl, monkeypatch):
    from rayvr.frame.passes import prefix_scan
    monkeypatch.setattr(prefix_scan, "MAX_GROUPS", 5)  # 12 groups of the key kernel and the sort: rows of 5
    rng = np.random.default_rng(23)
    capacity, count = 3000, 2600  # the batch's paths: the first `count` of the buffers' `capacity`
    paths = np.zeros(capacity, WAVE_PATH)
    o, d = random_rays(rng, capacity)
    paths["origin"][:, :3], paths["direction"][:, :3] = o, d
    paths["direction"][:, 3] = np.where(rng.random(capacity) < 0.2, -1.0, 10.0)  # tmax < 0: the path ended
    keys, order, (lo, scale) = gpu_order(gl, ray_order.ORDER_PATHS, paths, np.zeros(1, SHADOW_SLOT), count, capacity)
    expected = ray_order.order_keys(o[:count], d[:count], lo, scale)
    ended = paths["direction"][:count, 3] < 0
    expected[ended] = ray_order.ORDER_KEY_NONE
    assert np.array_equal(keys[:count, 0], expected) and np.array_equal(keys[:count, 1], np.arange(count))
    assert len(set(expected[~ended].tolist())) > 100  # the keys really spread the rays
    assert np.array_equal(order[:count, 1], np.argsort(expected, kind="stable"))  # a permutation of the batch
    assert np.all(np.diff(order[:count, 0].astype(np.int64)) >= 0)
    assert np.all(keys[count:] == 0xABCDEF01)  # past the count: neither keyed nor sorted
    assert np.all(order[count:] == 0xABCDEF01)


def test_shadow_items_are_keyed_by_their_first_shadow_ray(gl):
    rng = np.random.default_rng(5)
    capacity, count = 700, 650
    paths = np.zeros(capacity, WAVE_PATH)
    n_rays = rng.integers(0, 3, capacity).astype(np.uint32)  # an item with none has no key
    paths["throughput"][:, 3] = n_rays.view(np.float32)
    shadows = np.zeros(2 * capacity, SHADOW_SLOT)
    o, d = random_rays(rng, 2 * capacity)
    shadows["origin"][:, :3], shadows["direction"][:, :3] = o, d
    keys, order, (lo, scale) = gpu_order(gl, ray_order.ORDER_SHADOWS, paths, shadows, count, capacity, items=0)
    expected = ray_order.order_keys(o[:count], d[:count], lo, scale)
    expected[n_rays[:count] == 0] = ray_order.ORDER_KEY_NONE
    assert np.array_equal(keys[:count, 0], expected)
    assert np.array_equal(order[:count, 1], np.argsort(expected, kind="stable"))


def render_room(gl, effect, order="none", persistent="off", **renderer):
    settings = RenderSettings(ray_order=order, persistent=persistent)
    with Renderer(None, parse_config({"default": effect}, "t"), gl=gl, settings=settings, **renderer) as r:
        rig = camera_rig(r, "pinhole", size=(24, 16))
        frame = r.render(rig, aux=("hdr",))
        # the last batch's paths: the first wave_args[1].w entries (the rest of the buffer is whatever
        # memory it was given: never written, never read). A path's slot follows its pixel's place in
        # the classify pass's list, which atomics fill in whatever order the GPU's threads run (on
        # llvmpipe under load, another order each run), so the hits are compared as a set of rows.
        paths = np.frombuffer(r.resource(f"rt_wave.{effect}.args").read(), np.uint32).reshape(-1, 4)[1, 3]
        hits = np.frombuffer(r.resource(f"rt_wave.{effect}.paths").read(), WAVE_PATH)["hit"][:paths]
        hits = hits[np.lexsort(hits.T[::-1])].copy()
        assert r.plan().ray_order == order and r.plan().persistent == (persistent == "on")
        return [(e.aux["hdr"].copy(), e.color.copy()) for e in (frame.left, frame.right)], hits


@pytest.mark.parametrize("effect", ["glossy", "path", "photon", "shadows"])
def test_reordered_and_persistent_wavefronts_give_the_default_frames_exactly(gl, effect):
    reference, ref_hits = render_room(gl, effect)
    assert any(np.any(hdr[..., :3] > 0) for hdr, _ in reference)
    # photon and shadows trace no closest hits: their paths' hit fields are never written and hold
    # whatever memory the buffer was given (on NVIDIA, the last renderer's), so only frames compare
    traces_hits = effect in ("glossy", "path")
    if traces_hits:
        assert np.any((ref_hits[:, 0] != 0xFFFFFFFE) & (ref_hits[:, 0] != 0xFFFFFFFF))  # real hits to compare
    for order, persistent in VARIANTS:
        eyes, hits = render_room(gl, effect, order, persistent)
        assert not traces_hits or np.array_equal(hits, ref_hits), (order, persistent)
        for (hdr, color), (ref_hdr, ref_color) in zip(eyes, reference):
            assert np.array_equal(hdr, ref_hdr), (order, persistent)
            assert np.array_equal(color, ref_color), (order, persistent)


def test_batches_and_shadow_chunks_reorder_and_fetch_exactly_too(gl):
    """A small wave-buffer limit splits the pixel list into batches and the shadow rays into chunks:
    each trace kernel of each batch sorts its own rays and has its own ray counter. The frames hold
    every batch's paths and must be equal; the buffer holds only the last batch's, whose pixels are
    whichever the classify pass's atomics put last (on the H200, other pixels each render), so of
    its hits only the count compares."""
    limit = 16 * 1024
    reference, ref_hits = render_room(gl, "glossy", wave_buffer_bytes=limit)
    eyes, hits = render_room(gl, "glossy", "morton", "on", wave_buffer_bytes=limit)
    for (hdr, color), (ref_hdr, ref_color) in zip(eyes, reference):
        assert np.array_equal(hdr, ref_hdr) and np.array_equal(color, ref_color)
    assert 0 < len(hits) == len(ref_hits) < 24 * 16  # batched: the last batch is not the whole list



def test_bench_takes_the_options_as_grid_axes_and_refuses_a_bad_value_in_one_line(capsys):
    from rayvr.bench import wavefront_variants
    from rayvr.cli import build_parser

    def variants(*argv):
        return wavefront_variants(build_parser().parse_args(["bench", "vr", *argv]))
    assert variants() is None  # neither asked for: the benches run as before
    assert variants("--ray-order", "none,morton", "--persistent", "on") == {
        "ray_order=none,persistent=on": {"ray_order": "none", "persistent": "on"},
        "ray_order=morton,persistent=on": {"ray_order": "morton", "persistent": "on"}}
    assert list(variants("--persistent", "off,on")) == ["ray_order=none,persistent=off", "ray_order=none,persistent=on"]
    for flag, text, what in (("--ray-order", "none,hilbert", "ray orders must be among none, morton"),
                             ("--persistent", "yes", "persistent modes must be among off, on")):
        with pytest.raises(SystemExit) as exc:
            build_parser().parse_args(["bench", "rays", flag, text])
        lines = capsys.readouterr().err.strip().splitlines()
        assert exc.value.code == 2 and len(lines) == 1 and what in lines[0], lines
