"""PNG encoders for a capture's colour images, measured on real rayvr frames (issue 24).

    python encoders.py OUT.json IMAGE.png [IMAGE.png ...]

For each image: each encoder at each compression level, one at a time (seconds per image, bytes);
then Pillow on a pool of N threads against N processes (images per second, the best of REPEAT
rounds, threads and processes taking turns so that the host's other load falls on both alike); and
the share of one-thread encoding time in which a pure-Python thread ticking beside it (1 ms sleeps)
was kept from running for over STARVED_S: the most the encoder holds the GIL. Encoders whose package
is missing are left out of the table (imagecodecs, opencv-python-headless: not rayvr dependencies).
Every encoding is decoded again and compared with the source pixels: a lossy result fails the run.
"""
from __future__ import annotations

import io
import json
import os
import platform
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import numpy as np
from PIL import Image

LEVELS = (0, 1, 2, 3, 6, 9)
REPEAT = 3  # the best of REPEAT timings: the host is shared
STARVED_S = 0.005


def pillow(a, level):
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG", compress_level=level)
    return buf.getvalue()


def encoders() -> dict:
    found = {"pillow": pillow}
    try:
        import imagecodecs

        found["imagecodecs.png"] = lambda a, level: imagecodecs.png_encode(a, level=level)
        found["imagecodecs.spng"] = lambda a, level: imagecodecs.spng_encode(a, level=level)
    except ImportError:
        pass
    try:
        import cv2

        found["opencv"] = lambda a, level: cv2.imencode(".png", a[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, level])[1].tobytes()
    except ImportError:
        pass
    return found


def best_time(fn, *args):
    times = []
    for _ in range(REPEAT):
        t = time.perf_counter()
        out = fn(*args)
        times.append(time.perf_counter() - t)
    return min(times), out


def pool_rate(pool, workers: int, images: list, count: int, level: int) -> float:
    """Images per second encoding `count` images with Pillow at `level` on a started pool."""
    work = [images[i % len(images)] for i in range(count)]
    t = time.perf_counter()
    list(pool.map(pillow, work, [level] * count))
    return count / (time.perf_counter() - t)


def gil_held_share(image, level: int, count: int = 6) -> float:
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
    ticker.start()
    t = time.perf_counter()
    for _ in range(count):
        pillow(image, level)
    wall = time.perf_counter() - t
    stop.set()
    ticker.join()
    return starved[0] / wall


def main(out: str, paths: list[str]) -> None:
    images = {Path(p).name: np.asarray(Image.open(p).convert("RGB")) for p in paths}
    table = []
    for name, a in images.items():
        for enc, fn in encoders().items():
            for level in LEVELS:
                seconds, data = best_time(fn, a, level)
                same = np.array_equal(np.asarray(Image.open(io.BytesIO(data)).convert("RGB")), a)
                assert same, f"{enc} level {level} is not lossless on {name}"
                table.append({"image": name, "encoder": enc, "level": level, "seconds": seconds,
                              "bytes": len(data), "raw_bytes": a.nbytes})
                print(f"{name:24s} {enc:18s} {level}  {seconds * 1000:8.1f} ms  {len(data) / 2**20:7.2f} MiB", flush=True)
    pools = []
    cores = os.cpu_count() or 1
    for level in (1, 6):
        for workers in sorted({1, 2, cores}):
            best = {"threads": 0.0, "processes": 0.0}
            with ThreadPoolExecutor(workers) as threads, ProcessPoolExecutor(workers) as processes:
                started = {"threads": threads, "processes": processes}
                for pool in started.values():
                    list(pool.map(pillow, list(images.values())[:1] * workers, [level] * workers))  # started
                for _ in range(REPEAT):
                    for kind, pool in started.items():
                        best[kind] = max(best[kind], pool_rate(pool, workers, list(images.values()), 4 * workers, level))
            for kind, rate in best.items():
                pools.append({"kind": kind, "workers": workers, "level": level, "images_per_s": rate,
                              "load_average": os.getloadavg()})  # the host's other work, while measured
                print(f"pillow level {level} {kind:9s} x{workers}: {rate:6.2f} images/s", flush=True)
    gil = []
    for name, a in images.items():
        for level in (1, 6):
            share = gil_held_share(a, level)
            gil.append({"image": name, "level": level, "starved_share": share})
            print(f"GIL: {name} level {level}: a Python thread starved {100 * share:.1f} % of the time", flush=True)
    Path(out).write_text(json.dumps({
        "machine": {"host": platform.node(), "cpu_count": cores, "processor": platform.processor() or platform.machine(),
                    "note": "shared with other jobs: timings are the best of %d" % REPEAT},
        "images": {n: list(a.shape) for n, a in images.items()}, "encode": table, "pools": pools, "gil": gil,
        "versions": {m: getattr(sys.modules.get(m), "__version__", None) for m in ("PIL", "imagecodecs", "cv2", "numpy")},
    }, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
