"""The write side of a capture alone (issue 24): rayvr's own write_frame (encode, atomic write,
frame record) through its FrameWriter, on frames made of real rendered eye images, so that the
figures say what the pipeline sustains when the GPU is not what limits it (on llvmpipe, rendering
takes the same cores and, inside moderngl's compute dispatches, the GIL: pipeline.py).

    python writer_pool.py OUT.json LEFT.png RIGHT.png

Each run writes FRAMES stereo frames (colour + the depth every capture reads back, not written
unless asked) into a fresh folder; frames/s is the best of REPEAT runs. On a host shared with other
work a pool cannot show how it scales, so each level is also written once with a pure-Python thread
ticking beside it (1 ms sleeps): the share of the time that thread could not run is the most the
writer held the GIL, an upper bound on what keeps threads from scaling with cores.
Run from the repository root.
"""
from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from PIL import Image

from rayvr.app.capture import CaptureJob, write_frame
from rayvr.app.writers import FrameWriter
from rayvr.frame.cameras.rig import StereoRig
from rayvr.frame.graph import EyeImage
from rayvr.renderer import Frame
from rayvr.scene.loader import load

FRAMES = 12
REPEAT = 5
STARVED_S = 0.005  # a tick later than this: the ticker was kept from running
RUNS = [("serial", 1, "png", 6), ("serial", 1, "png", 1), ("pool", 2, "png", 6), ("pool", 2, "png", 1),
        ("pool", 2, "png", 0), ("serial", 1, "npy", 1), ("pool", 2, "npy", 1)]


def frames_per_s(frame, writers: int, fmt: str, level: int, rig) -> float:
    best = 0.0
    for _ in range(REPEAT):
        with tempfile.TemporaryDirectory(dir=os.environ.get("BENCH_TMP")) as tmp:
            job = CaptureJob(rig, [rig.pose] * FRAMES, out_dir=Path(tmp), format=fmt, png_compression=level,
                             writers=writers)
            start = time.perf_counter()
            with FrameWriter(writers) as writer:
                for i in range(FRAMES):
                    writer.submit(i, lambda i=i: write_frame(job, i, frame, record="bench"))
                writer.finish()
            best = max(best, FRAMES / (time.perf_counter() - start))
    return best


def gil_held_share(frame, fmt: str, level: int, rig) -> float:
    """The share of one serial write of FRAMES frames in which a ticking thread was starved."""
    stop, starved = threading.Event(), [0.0]

    def tick():
        last = time.perf_counter()
        while not stop.is_set():
            time.sleep(0.001)
            now = time.perf_counter()
            if now - last > STARVED_S:
                starved[0] += now - last
            last = now

    ticker = threading.Thread(target=tick)
    with tempfile.TemporaryDirectory(dir=os.environ.get("BENCH_TMP")) as tmp:
        job = CaptureJob(rig, [rig.pose] * FRAMES, out_dir=Path(tmp), format=fmt, png_compression=level, writers=1)
        ticker.start()
        start = time.perf_counter()
        for i in range(FRAMES):
            write_frame(job, i, frame, record="bench")
        wall = time.perf_counter() - start
        stop.set()
        ticker.join()
    return starved[0] / wall


def main(out: str, left: str, right: str) -> None:
    eyes = {}
    for name, path in (("left", left), ("right", right)):
        color = np.asarray(Image.open(path).convert("RGB"))
        eyes[name] = EyeImage(name, color, np.zeros(color.shape[:2], np.float32))
    frame = Frame(eyes, {}, "color", ())
    h, w = eyes["left"].color.shape[:2]
    rig = StereoRig.for_scene(load(None), size=(w, h))
    runs = []
    for kind, writers, fmt, level in RUNS:
        rate = frames_per_s(frame, writers, fmt, level, rig)
        runs.append({"kind": kind, "writers": writers, "format": fmt, "png_compression": level,
                     "frames_per_s": rate})
        print(f"{kind:6s} x{writers} {fmt} level {level}: {rate:6.2f} stereo frames/s", flush=True)
    gil = [{"format": fmt, "png_compression": level, "starved_share": gil_held_share(frame, fmt, level, rig)}
           for fmt, level in (("png", 6), ("png", 1), ("png", 0), ("npy", 1))]
    for g in gil:
        print(f"GIL: {g['format']} level {g['png_compression']}: a Python thread starved "
              f"{100 * g['starved_share']:.1f} % of the time", flush=True)
    Path(out).write_text(json.dumps({
        "machine": {"host": platform.node(), "cpu_count": os.cpu_count(),
                    "note": "2 cores shared with other jobs while measured; best of %d runs" % REPEAT},
        "images": {"left": left, "right": right, "size": [w, h], "eyes": 2}, "frames": FRAMES, "runs": runs, "gil": gil,
        "load_average": os.getloadavg()},
        indent=1) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
