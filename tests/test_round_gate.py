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


def test_the_gate_refuses_more_grids_than_it_sizes(gl, gate):
    count_buf = gl.ctx.buffer(np.array([1], np.uint32).tobytes())
    count_buf.bind_to_storage_buffer(SSBO["msaa_count"])
    gate.open(SimpleNamespace(resources={}), 0)
    program = gl.ctx.compute_shader(COUNTER.replace("binding = 37", "binding = 38"))
    scratch = gl.ctx.buffer(reserve=4)
    scratch.bind_to_storage_buffer(38)
    for i in range(GATE_GRIDS):
        gate.dispatch(program, (i + 1, 1, 1))
    with pytest.raises(RuntimeError, match="at most"):
        gate.dispatch(program, (GATE_GRIDS + 1, 1, 1))
    for b in (count_buf, program, scratch):
        b.release()
