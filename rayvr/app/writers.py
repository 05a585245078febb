"""Encoding and writing a capture's frames on a pool of threads while the GPU renders the next ones.

The PNG encoder (util/png.py: one zlib call), np.save and the file writes release the GIL, so
threads encode frames side by side without copying them to other processes and leave the render
thread the GIL (measured against processes and other encoders: docs/capture.md). The queue is bounded: rendering waits while `limit` frames are read back
and not yet written, so a 10,000-frame path holds as much memory as a short one. Frames finish in the
order they were handed in; the first one that fails (an unwritable folder, a full disk) is raised
where the capture loop waits, and the frames queued behind it are not written.

One writer (`--writers 1`) writes each frame in the capture's own thread as it comes back: the
serial path, which the pooled one is tested against byte for byte.
"""
from __future__ import annotations

import contextlib
import os
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

MAX_DEFAULT_WRITERS = 16  # past this a capture is bound by the GPU or the disk, not the encoders
QUEUED_PER_POOL = 2  # frames waiting beyond one per thread: a thread never idles between two frames
PNG_COMPRESSION_LEVELS = range(10)  # zlib's levels: 0 stores, 9 compresses hardest
# zlib level 1: on a shaded frame 3.4 times the speed of Pillow's own default (6) for a file no
# larger; a flat raster frame's is up to 1.8 times larger (docs/capture.md)
DEFAULT_PNG_COMPRESSION = 1


def default_writers() -> int:
    """Writer threads by default: one per core this process may run on, at most MAX_DEFAULT_WRITERS."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform
        cores = os.cpu_count() or 1
    return max(1, min(MAX_DEFAULT_WRITERS, cores))


def writers_per_worker(writers: int | None, workers: int, local: bool) -> int | None:
    """Each Ray worker's writer threads: as asked, or when not asked and every worker runs on this
    host (no --address), this host's default shared out among them (one per core each would make
    workers x cores threads); None, a worker elsewhere, takes its own host's default."""
    if writers is not None or not local:
        return writers
    return max(1, default_writers() // max(1, workers))


def check_png_compression(level) -> int:
    """`level` if it is one of zlib's levels 0..9, else ValueError saying what is allowed."""
    if isinstance(level, bool) or not isinstance(level, int) or level not in PNG_COMPRESSION_LEVELS:
        raise ValueError(f"PNG compression must be a whole number from {PNG_COMPRESSION_LEVELS[0]} to "
                         f"{PNG_COMPRESSION_LEVELS[-1]}, got {level!r}")
    return level


def check_writers(count) -> int:
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"writers must be a positive whole number, got {count!r}")
    return count


class FrameWriter:
    """Runs frame writes (`submit(index, task)`, task() -> its result) on `threads` threads, at
    most `limit` at once (queued or running); with one thread, in the caller's thread at once.
    `submit` and `finish` return the (index, result)s of the frames written meanwhile, in the
    order they were handed in. Use as a context manager: leaving it waits for the writes started
    (every file is written atomically, so what they leave is whole) and drops those queued."""

    def __init__(self, threads: int, limit: int | None = None):
        self.threads = check_writers(threads)
        self.limit = limit if limit is not None else threads + QUEUED_PER_POOL
        if self.limit < 1:
            raise ValueError(f"a writer queue holds at least one frame, got {self.limit}")
        self._pool = ThreadPoolExecutor(threads, thread_name_prefix="rayvr-writer") if threads > 1 else None
        self._pending: deque[tuple[int, Future]] = deque()
        self._written: list = []  # (index, result)s collected and not yet returned
        self.peak = 0  # the most frames in flight at once

    def submit(self, index: int, task) -> list:
        """Hand frame `index`'s write over; returns once fewer than `limit` frames are in flight,
        so that the next frame is read back only when there is room for it."""
        if self._pool is None:
            self.peak = 1
            self._written.append((index, task()))
            return self._take()
        self._pending.append((index, self._pool.submit(task)))
        self.peak = max(self.peak, len(self._pending))
        while self._pending and (self._pending[0][1].done() or len(self._pending) >= self.limit):
            self._collect_oldest()
        return self._take()

    def finish(self) -> list:
        """Wait for every frame handed over."""
        while self._pending:
            self._collect_oldest()
        return self._take()

    def settle(self) -> list:
        """After an interrupt: drop the queued frames and wait for those being written; the frames
        that were written (a failure among them is not raised: the interrupt is the news)."""
        for _, future in self._pending:
            future.cancel()
        for index, future in self._pending:
            if not future.cancelled() and future.exception() is None:
                self._written.append((index, future.result()))
        self._pending.clear()
        return self._take()

    def in_flight(self) -> int:
        return len(self._pending)

    def _collect_oldest(self) -> None:
        index, future = self._pending[0]
        result = future.result()  # a failed write raises here, in the capture's thread
        self._pending.popleft()
        self._written.append((index, result))

    def _take(self) -> list:
        taken, self._written = self._written, []
        return taken

    def __enter__(self) -> "FrameWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Let the writes already running end; drop the queued ones (their frames are not written)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._pending.clear()


class PipelineTimes:
    """Where a capture's time goes, per frame: the GPU (its timer queries, where they mean
    something), rendering (recording the frame and waiting for the GPU), the read-back (mapping the
    pixel buffers, `reader.finish_s`) and waiting for the writers (or writing, with one)."""

    def __init__(self, reader, meaningful: bool):
        self.reader, self.meaningful = reader, meaningful
        self.frames, self.gpu_ms, self.render_s, self.write_s = 0, 0.0, 0.0, 0.0
        self._readback_start = self._readback()
        self._start = time.perf_counter()

    def _readback(self) -> float:
        return getattr(self.reader, "finish_s", 0.0)

    @contextlib.contextmanager
    def _timed(self, total: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            setattr(self, total, getattr(self, total) + time.perf_counter() - start)

    def rendering(self):
        return self._timed("render_s")

    def writing(self):
        return self._timed("write_s")

    def frame_done(self, frame_gpu_ms: float) -> None:
        self.frames += 1
        self.gpu_ms += frame_gpu_ms

    def per_frame_ms(self) -> dict:
        n = max(1, self.frames)
        readback = self._readback() - self._readback_start
        return {"gpu": self.gpu_ms / n if self.meaningful else None,
                "render": 1000 * (self.render_s - readback) / n,  # recording, and waiting for the GPU
                "readback": 1000 * readback / n, "write_wait": 1000 * self.write_s / n}

    def describe(self) -> str:
        """The progress bar's note, e.g. "GPU 4.1, render 6, read-back 3, write wait 1 ms/frame"."""
        return describe_ms(self.per_frame_ms())

    def summary(self, writer: FrameWriter, png_compression: int) -> dict:
        wall = time.perf_counter() - self._start
        return {"writers": writer.threads, "queue_limit": writer.limit, "peak_in_flight": writer.peak,
                "png_compression": png_compression, "frames": self.frames, "wall_s": wall,
                "frames_per_s": self.frames / wall if wall > 0 else None, "ms_per_frame": self.per_frame_ms()}


def merge_pipelines(parts: list[dict]) -> dict:
    """The pipeline summary of a capture run in parts (Ray workers' tasks): frames summed, each
    per-frame time the mean over all frames, the writers and queue of one part (every worker
    writes with the same)."""
    parts = [p for p in parts if p and p.get("frames")]
    if not parts:
        return {}
    frames = sum(p["frames"] for p in parts)

    def mean(key):
        values = [(p["ms_per_frame"][key], p["frames"]) for p in parts if p["ms_per_frame"][key] is not None]
        return sum(v * n for v, n in values) / sum(n for _, n in values) if values else None

    return {"writers": parts[0]["writers"], "queue_limit": parts[0]["queue_limit"],
            "peak_in_flight": max(p["peak_in_flight"] for p in parts), "png_compression": parts[0]["png_compression"],
            "frames": frames, "tasks": len(parts), "ms_per_frame": {k: mean(k) for k in parts[0]["ms_per_frame"]}}


def describe_ms(ms: dict) -> str:
    """A progress bar's note from per-frame milliseconds (PipelineTimes.per_frame_ms)."""
    gpu = f"GPU {ms['gpu']:.1f}" if ms.get("gpu") is not None else "GPU n/a"
    return f"{gpu}, render {ms['render']:.0f}, read-back {ms['readback']:.0f}, write wait {ms['write_wait']:.0f} ms/frame"
