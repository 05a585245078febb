"""Image metrics off the render thread. FLIP and SSIM hold the GIL for about a second each at
2x1440x1600, so a sweep (bench tradeoff, bench budget, --budget-ms) judges each measured image
in worker processes while the GPU renders the next variant. Without spare cores (a 2-core CI
host) the metrics run inline, in order: the numbers are the same either way."""
from __future__ import annotations

import atexit
import multiprocessing
import os
from collections import deque
from concurrent.futures import Future, ProcessPoolExecutor

CORES_PER_WORKER = 4  # FLIP's own threads use a few cores; one worker per four keeps them busy
MAX_WORKERS = 4
PENDING_PER_WORKER = 2  # images waiting beyond this block the sweep: each holds two full frames

_pool: ProcessPoolExecutor | None = None
_pending: deque = deque()


def workers() -> int:
    """Worker processes the metrics get here (RAYVR_METRIC_WORKERS overrides; 0: inline)."""
    if "RAYVR_METRIC_WORKERS" in os.environ:
        return max(0, int(os.environ["RAYVR_METRIC_WORKERS"]))
    return min(MAX_WORKERS, (os.cpu_count() or 1) // CORES_PER_WORKER)


def judge(fn, *args) -> Future:
    """fn(*args) in a worker process (started on first use, kept for the process's life), or
    inline without workers; a Future of its result either way. `fn` must be importable."""
    global _pool
    n = workers()
    if n == 0:
        done: Future = Future()
        done.set_result(fn(*args))
        return done
    if _pool is None:
        # spawn, not fork: this process holds a GL context and driver threads
        _pool = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("spawn"))
    while _pending and _pending[0].done():
        _pending.popleft()
    while len(_pending) >= n * PENDING_PER_WORKER:
        _pending.popleft().result()  # back-pressure: wait for the oldest image
    future = _pool.submit(fn, *args)
    _pending.append(future)
    return future


@atexit.register
def shutdown() -> None:
    """End the worker processes (at exit; a later judge() starts them again)."""
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=True, cancel_futures=True)
        _pool = None
    _pending.clear()
