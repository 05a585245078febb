"""The round gate (frame/passes/round_gate.py, glsl/rt/round_gate.comp): a round within its channel
set's count (one at least) dispatches each grid it was asked for, a round past it nothing and empties
the traced effects' pixel lists. Frames through the gate equal frames without it:
tests/test_msaa_rounds.py (every round after the first is gated when the count is never known)."""
from types import SimpleNamespace

import numpy as np
import pytest

from rayvr.frame.passes.classify import args_bytes, list_slots
from rayvr.frame.passes.round_gate import GATE_GRIDS, RoundGate
from rayvr.gl.gpu_layout import SSBO

# counts every invocation it runs (binding clear of the gate's and the lists')
COUNTER = """#version 430
layout(local_size_x = 2, local_size_y = 2) in;
layout(std430, binding = 37) buffer Counter { uint invocations; };
void main() { atomicAdd(invocations, 1u); }
"""
GRIDS = [(5, 3, 2), (2, 1, 2)]


@pytest.fixture
def gate(gl):
    g = RoundGate(gl.ctx)
    yield g
    g.release()


def args_of(gate, n):
    return np.frombuffer(gate.args.read(), np.uint32).reshape(GATE_GRIDS, 4)[:n, :3].tolist()


@pytest.mark.parametrize("count", [0, 1, 3])
def test_the_gate_sizes_rounds_within_the_count_and_empties_the_rest(gl, gate, count):
    ctx = gl.ctx
    count_buf = ctx.buffer(np.array([count], np.uint32).tobytes())
    count_buf.bind_to_storage_buffer(SSBO["msaa_count"])
    lists = ctx.buffer(np.full(args_bytes() // 4, 7, np.uint32).tobytes())
    fc = SimpleNamespace(resources={"rt_list_args": lists})
    counter = ctx.buffer(reserve=4)
    counter.bind_to_storage_buffer(37)
    program = ctx.compute_shader(COUNTER)
    try:
        for ordinal in range(5):
            lists.write(np.full(args_bytes() // 4, 7, np.uint32).tobytes())
            gate.open(fc, ordinal)
            within = ordinal < max(count, 1)
            counter.write(bytes(4))
            for grid in GRIDS:   # the first round asks for them for the first time: the gate runs again
                gate.dispatch(program, grid)
            ctx.finish()
            ran = int(np.frombuffer(counter.read(), np.uint32)[0])
            per_group = 4
            assert ran == (sum(per_group * x * y * z for x, y, z in GRIDS) if within else 0), (ordinal, count)
            assert args_of(gate, 2) == ([list(g) for g in GRIDS] if within else [[0, 1, 1]] * 2)
            words = np.frombuffer(lists.read(), np.uint32)
            slots = list_slots()
            if within:
                assert (words == 7).all()   # a round within the count leaves classify's lists alone
            else:
                assert words[:4 * slots].reshape(slots, 4).tolist() == [[0, 1, 1, 0]] * slots
                assert (words[4 * slots:] == 7).all()   # the running counts stay classify's (zero)
    finally:
        for b in (count_buf, lists, counter, program):
            b.release()


def test_a_gate_without_traced_effects_needs_no_lists(gl, gate):
    count_buf = gl.ctx.buffer(np.array([2], np.uint32).tobytes())
    count_buf.bind_to_storage_buffer(SSBO["msaa_count"])
    gate.grids = [GRIDS[0]]
    gate.open(SimpleNamespace(resources={}), 2)
    gl.ctx.finish()
    assert args_of(gate, 1) == [[0, 1, 1]]
    gate.open(SimpleNamespace(resources={}), 1)
    gl.ctx.finish()
    assert args_of(gate, 1) == [list(GRIDS[0])]
    count_buf.release()


def test_a_full_gate_starts_its_table_over_and_still_sizes_every_dispatch(gl, gate):
    """Frame sizes come and go (a preview window resized): past GATE_GRIDS grids the table starts over,
    and every dispatch, before and after, runs the grid it asked for (commands run in order)."""
    count_buf = gl.ctx.buffer(np.array([1], np.uint32).tobytes())
    count_buf.bind_to_storage_buffer(SSBO["msaa_count"])
    counter = gl.ctx.buffer(reserve=4)
    counter.bind_to_storage_buffer(37)
    program = gl.ctx.compute_shader(COUNTER)
    gate.open(SimpleNamespace(resources={}), 0)
    counter.write(bytes(4))
    grids = [(i + 1, 1, 1) for i in range(GATE_GRIDS + 3)]
    for grid in grids:
        gate.dispatch(program, grid)
    gl.ctx.finish()
    assert int(np.frombuffer(counter.read(), np.uint32)[0]) == 4 * sum(g[0] for g in grids)
    assert len(gate.grids) == 3
    for b in (count_buf, program, counter):
        b.release()


@pytest.mark.parametrize("listed", [0, 5, 70000, 90000])
def test_the_listed_tiles_dispatch_one_workgroup_a_tile_in_rows_gl_allows(gl, gate, listed):
    """After a round's select (GATE_TILES): the select's count becomes the dispatch size, in rows of
    at most 65535 workgroups (GL's least limit a dimension), or the frame's own grid where more than
    half its tiles are listed; the count restarts for the next round."""
    grid = (400, 200, 2)   # 160000 tiles
    tiles = gl.ctx.buffer(np.array([9, 9, 9, 9, listed, 9], np.uint32).tobytes())
    gate.list_tiles(tiles, grid)
    gl.ctx.finish()
    args = np.frombuffer(tiles.read(), np.uint32).tolist()
    if 2 * listed > 400 * 200 * 2:
        assert args == [*grid, listed, 0, 1]
    else:
        rows = -(-listed // 65535)
        assert args == [min(listed, 65535), max(rows, 1), 1, listed, 0, 0]
        assert args[0] * args[1] >= listed   # every tile gets a workgroup (round_pixel drops the rest)
    tiles.release()


@pytest.fixture(scope="module")
def room():
    from rayvr.scene.loader import load

    return load(None)


@pytest.mark.parametrize("case", ["traced 8x", "shared chromatic 4x", "ssr 4x"])
def test_frames_over_listed_tiles_equal_frames_over_the_whole_frame(gl, room, count_poll, monkeypatch, case):
    """The gbuffer resolve, shade and sample_accumulate of each MSAA round run over the tiles its select
    listed (tiles holding a pixel the round shades), not the whole frame: the same frame, colour,
    depth and every aux channel, also where the count is never known while recording (rounds past it
    list nothing) and where empty slots are shaded as background (ssr: they are listed)."""
    from rayvr import Renderer
    from rayvr.frame.cameras import Distorted
    from rayvr.frame.cameras.rig import Pose, StereoRig
    from rayvr.frame.passes import round_gate
    from rayvr.renderer import RenderSettings
    from rayvr.scene.materials import parse_config

    aux = ("hdr", "position", "normal", "albedo", "material", "triangle")
    samples = int(case.split()[-1].rstrip("x"))
    chromatic = Distorted(coefficients=((0.1, 0.0, 0.0), (0.2, 0.0, 0.0), (0.3, 0.0, 0.0)))
    camera = chromatic if "chromatic" in case else None
    materials = {"traced 8x": "rayvr/assets/default_room.toml",
                 "ssr 4x": parse_config({"materials": {"floor": {"effect": "ssr"}}}, "<listed tiles ssr>")}.get(case)
    # the room's ceiling corner: up to 3 triangles in a pixel, most pixels one (few tiles listed past slot 0)
    rig = StereoRig(Pose.look_at([0.3, 1.5, 1.0], [0.3, 2.5, -1]), ipd=0.064, fov_y=60, size=(40, 24), near=1e-3,
                    **({"camera": camera} if camera else {}))
    settings = RenderSettings(msaa=samples, share_channel_shading="shared" in case)
    frames = {}
    for poll in ("wait", "never"):
        for listed in (False, True):
            count_poll(poll)
            monkeypatch.setattr(round_gate, "LIST_TILES", listed)
            with Renderer(room, materials, gl=gl, settings=settings) as r:
                frames[poll, listed] = r.render(rig, aux=aux)
    ref = frames["wait", False]
    assert ref.left.color.max() > 0
    for key, got in frames.items():
        for eye in ("left", "right"):
            np.testing.assert_array_equal(got[eye].color, ref[eye].color, err_msg=f"{key} {eye}")
            np.testing.assert_array_equal(got[eye].depth, ref[eye].depth, err_msg=f"{key} {eye}")
            for name in aux:
                np.testing.assert_array_equal(got[eye].aux[name], ref[eye].aux[name], err_msg=f"{key} {eye} {name}")


def test_one_renderer_at_two_frame_sizes_gates_and_lists_each(gl, room, count_poll, monkeypatch):
    """A renderer whose frames change size (a preview window resized) sizes each round's gate and
    tile list for the frame at hand: every frame equals a fresh renderer's frame of its size, with the
    count never known while recording (every round after the first gated) and known after the first."""
    from rayvr import Renderer
    from rayvr.frame.cameras.rig import Pose, StereoRig
    from rayvr.renderer import RenderSettings

    pose = Pose.look_at([0.3, 1.5, 1.0], [0.3, 2.5, -1])
    rigs = [StereoRig(pose, ipd=0.064, fov_y=60, size=size, near=1e-3) for size in ((40, 24), (24, 40), (40, 24))]
    settings = RenderSettings(msaa=4)
    count_poll("wait")
    refs = []
    for rig in rigs[:2]:
        with Renderer(room, "rayvr/assets/default_room.toml", gl=gl, settings=settings) as r:
            refs.append(r.render(rig))
    count_poll("never")
    with Renderer(room, "rayvr/assets/default_room.toml", gl=gl, settings=settings) as r:
        got = [r.render(rig) for rig in rigs]
    for frame, ref in zip(got, [refs[0], refs[1], refs[0]]):
        for eye in ("left", "right"):
            assert frame[eye].color.shape == ref[eye].color.shape
            np.testing.assert_array_equal(frame[eye].color, ref[eye].color)
            np.testing.assert_array_equal(frame[eye].depth, ref[eye].depth)
