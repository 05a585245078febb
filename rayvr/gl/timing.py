"""GPU timing helpers: valid timer readings only, and warming a GPU up until its times settle.

An idle GPU runs at a fraction of its clock (the one measured idles at 345 MHz against 1980 MHz), and
the first frames after a renderer is built ran 2-4x slow there even after 0.3 s of work (every
pass, tonemapping too). A fixed warm-up is therefore not enough: `settle()` repeats a step until
the times of the last few runs agree with the few before them.
"""
from __future__ import annotations

import ctypes
import statistics
import time

from .context import is_software_renderer

GL_TIME_ELAPSED, GL_QUERY_RESULT = 0x88BF, 0x8866


class TimerQuery:
    """A GL_TIME_ELAPSED query read as 64 bits (moderngl's queries read 32: a pass over 4.29 s
    saturates at 4294967295 ns). `with q:` times the GL work recorded inside; `elapsed` waits."""

    def __init__(self, raw):
        self.raw = raw
        name = ctypes.c_uint()
        raw.glGenQueries(1, ctypes.byref(name))
        self.name = name.value

    def __enter__(self):
        self.raw.glBeginQuery(GL_TIME_ELAPSED, self.name)
        return self

    def __exit__(self, *exc):
        self.raw.glEndQuery(GL_TIME_ELAPSED)

    @property
    def elapsed(self) -> int:
        ns = ctypes.c_uint64()
        self.raw.glGetQueryObjectui64v(self.name, GL_QUERY_RESULT, ctypes.byref(ns))
        return ns.value

    def release(self) -> None:
        self.raw.glDeleteQueries(1, ctypes.byref(ctypes.c_uint(self.name)))

# llvmpipe reads a raster pass's timer back as garbage now and then: 4294967295 ns through 32
# bits; through 64, the end timestamp alone (~ the machine's uptime: 3164585 ms was seen). No GPU
# work takes longer than the wall time since it was recorded: a reading over that is garbage.
WALL_SLACK_NS = 10**6


def valid_elapsed_ns(ns: int, wall_ns: float | None = None) -> bool:
    """A plausible timer reading: not negative, not the 32-bit saturation value, and not longer
    than `wall_ns`, the real time since the work was recorded (when known)."""
    if ns < 0 or ns == 0xFFFFFFFF or ns >= 1 << 63:
        return False
    return wall_ns is None or ns <= wall_ns + WALL_SLACK_NS


def settle(step, min_seconds: float = 0.3, max_seconds: float = 10.0, window: int = 5,
           tolerance: float = 0.03) -> dict:
    """Call `step()` (which returns a time, e.g. GPU ms of a frame, after waiting for the GPU)
    until at least `min_seconds` have passed and the median of the last `window` results is
    within `tolerance` of the median of the `window` before; give up after `max_seconds`.
    Returns {"runs", "seconds", "settled", "last"} for the record."""
    start, times = time.perf_counter(), []
    while True:
        times.append(float(step()))
        elapsed = time.perf_counter() - start
        if len(times) >= 2 * window and elapsed >= min_seconds:
            now, before = statistics.median(times[-window:]), statistics.median(times[-2 * window:-window])
            if abs(now - before) <= tolerance * max(before, 1e-9):
                return {"runs": len(times), "seconds": elapsed, "settled": True, "last": now}
        if elapsed >= max_seconds:
            return {"runs": len(times), "seconds": elapsed, "settled": False, "last": times[-1]}


def time_gpu(ctx, fn, repeats: int = 10, min_seconds: float = 1.0, batches: int = 5) -> dict:
    """GPU ms of `fn()` (which records GL work) once the times settle: the median of `batches`
    timer queries around `repeats` calls each, with min and max; `ms` is the wall time per call
    where the timer reads ~0 (llvmpipe does for compute). A software rasterizer has no clock to
    ramp up: one call warms it."""
    query = ctx.query(time=True)

    def one() -> float:
        with query:
            fn()
        return query.elapsed / 1e6

    if is_software_renderer(ctx):
        one()
    else:
        settle(one, min_seconds=min_seconds)
    gpu, wall = [], []
    for _ in range(batches):
        t0 = time.perf_counter()
        with query:
            for _ in range(repeats):
                fn()
        gpu.append(query.elapsed / 1e6 / repeats)
        ctx.finish()
        wall.append((time.perf_counter() - t0) * 1e3 / repeats)
    g, w = statistics.median(gpu), statistics.median(wall)
    return {"gpu_ms": g, "gpu_ms_min": min(gpu), "gpu_ms_max": max(gpu), "wall_ms": w, "ms": g if g > 0.01 * w else w}
