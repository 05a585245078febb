"""GPU timing helpers: valid timer readings only, and warming a GPU up until its times settle.

An idle GPU runs at a fraction of its clock (the H200 idles at 345 MHz against 1980 MHz), and
the first frames after a renderer is built ran 2-4x slow there even after 0.3 s of work (every
pass, tonemapping too). A fixed warm-up is therefore not enough: `settle()` repeats a step until
the times of the last few runs agree with the few before them.
"""
from __future__ import annotations

import statistics
import time

# A timer query whose end came before its begin reads back as a wrapped 32-bit value (llvmpipe
# gives 4294967295 ns for a raster pass now and then): nothing real lands in [2^31, 2^32) ns.
_WRAPPED_NS = (1 << 31, 1 << 32)


def valid_elapsed_ns(ns: int) -> bool:
    return ns >= 0 and not (_WRAPPED_NS[0] <= ns < _WRAPPED_NS[1])


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
