"""GPU timing helpers (rayvr/gl/timing.py): settling waits out a GPU's clock ramp; a software
rasterizer has none to wait for."""
import itertools
import os
import time

import numpy as np
import pytest

from rayvr.gl import timing
from rayvr.gl.context import ContextError, create_context
from rayvr.gl.timing import settle, time_gpu, valid_elapsed_ns


def test_settle_stops_once_the_last_runs_agree_with_the_runs_before():
    # 10 runs getting faster (a GPU's clock ramping up: 20 ms down to 11), then a steady 1 ms from
    # run 11. The medians of the last 5 runs and the 5 before agree once 3 of the earlier 5 are
    # steady: runs 11-13 are 3 of runs 9-13, so run 18.
    times = itertools.chain(range(20, 10, -1), itertools.repeat(1.0))
    record = settle(lambda: float(next(times)), min_seconds=0.0, window=5)
    assert record["settled"] and record["runs"] == 18 and record["last"] == 1.0


def test_settle_gives_up_after_max_seconds_when_times_never_agree():
    times = (1.01 ** k for k in itertools.count())  # each window 5 % slower than the one before
    record = settle(lambda: next(times), min_seconds=0.0, max_seconds=0.05)
    assert not record["settled"] and record["seconds"] >= 0.05


def test_time_gpu_warms_a_software_rasterizer_with_one_call_and_settles_a_gpu(gl, monkeypatch):
    calls = []
    software = time_gpu(gl.ctx, lambda: calls.append(1), repeats=3, min_seconds=5.0, batches=2)
    assert gl.is_software is (len(calls) == 1 + 3 * 2)  # llvmpipe: no 5 s settle, one warm call
    assert software["ms"] >= 0 and software["gpu_ms_min"] <= software["gpu_ms"] <= software["gpu_ms_max"]
    calls.clear()
    monkeypatch.setattr(timing, "is_software_renderer", lambda ctx: False)
    time_gpu(gl.ctx, lambda: calls.append(1), repeats=3, min_seconds=0.0, batches=2)
    assert len(calls) >= 2 * 5 + 3 * 2  # two windows of settle() runs before the timed batches


def test_a_timer_reading_longer_than_the_wall_time_or_saturated_is_garbage():
    assert valid_elapsed_ns(1_000_000, wall_ns=2_000_000)
    assert not valid_elapsed_ns(0xFFFFFFFF)
    assert not valid_elapsed_ns(-1)
    assert not valid_elapsed_ns(3_164_585 * 10**6, wall_ns=10**7)  # the uptime llvmpipe once read back


def test_the_first_timer_query_of_a_new_context_reads_a_time_not_the_uptime():
    # llvmpipe had no scene to record the first query's start in: the first pass of every run
    # (visibility) read back the end timestamp alone and showed as "unavailable".
    try:
        fresh = create_context(os.environ.get("RAYVR_GL_BACKEND") or None)
    except ContextError as exc:
        pytest.skip(f"no OpenGL 4.3 context: {exc}")
    try:
        ctx = fresh.ctx
        program = ctx.program(vertex_shader="#version 330\nin vec2 p; void main() { gl_Position = vec4(p, 0, 1); }",
                              fragment_shader="#version 330\nout vec4 c; void main() { c = vec4(1); }")
        triangle = ctx.simple_vertex_array(program, ctx.buffer(np.array([-1, -1, 1, -1, 0, 1], "f4").tobytes()), "p")
        target = ctx.simple_framebuffer((64, 64))
        query = timing.TimerQuery(fresh.raw)
        start = time.perf_counter()
        with query:
            target.use()
            target.clear()
            triangle.render()
        ns = query.elapsed
        assert valid_elapsed_ns(ns, (time.perf_counter() - start) * 1e9), ns
    finally:
        fresh.release()
