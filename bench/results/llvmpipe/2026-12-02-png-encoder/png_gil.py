"""rayvr's PNG encoder (util/png.py) against Pillow's, on rendered frames: speed, size, and what
each does to a busy pure-Python thread beside it (the capture's render thread, recording GL calls,
is one).

    python png_gil.py OUT.json IMAGE.png [IMAGE.png ...]

For each image and level: seconds per image alone (best of REPEAT) and file size; then the same
encodes for SECONDS with a thread beside them that counts loop iterations in pure Python, giving
the encoder's seconds per image and the busy thread's rate as a share of its rate alone. Every
encoding is decoded with Pillow and compared with the source pixels.
"""
from __future__ import annotations

import io
import json
import os
import platform
import sys
import threading
import time
from pathlib import Path

import numpy as np
from PIL import Image

from rayvr.util.png import encode_png

REPEAT = 3
SECONDS = 3.0


def pillow(a, level):
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG", compress_level=level)
    return buf.getvalue()


def rayvr_png(a, level):
    return b"".join(encode_png(a, level))


ENCODERS = {"pillow": pillow, "rayvr.util.png": rayvr_png}


def busy_rate(seconds: float, beside=None) -> tuple[float, float]:
    """(iterations/s of a pure-Python loop, seconds per call of `beside` run meanwhile)."""
    stop, count = threading.Event(), [0]

    def spin():
        while not stop.is_set():
            for _ in range(1000):
                pass
            count[0] += 1

    thread = threading.Thread(target=spin)
    start = time.perf_counter()
    thread.start()
    calls = 0
    if beside is None:
        time.sleep(seconds)
    else:
        while time.perf_counter() - start < seconds:
            beside()
            calls += 1
    stop.set()
    thread.join()
    wall = time.perf_counter() - start
    return count[0] / wall, (wall / calls if calls else 0.0)


def main(out: str, paths: list[str]) -> None:
    images = {Path(p).parent.name + "/" + Path(p).name: np.asarray(Image.open(p).convert("RGB")) for p in paths}
    rows = []
    for name, a in images.items():
        for level in (1, 6):
            for enc, fn in ENCODERS.items():
                times = []
                for _ in range(REPEAT):
                    t = time.perf_counter()
                    data = fn(a, level)
                    times.append(time.perf_counter() - t)
                assert np.array_equal(np.asarray(Image.open(io.BytesIO(data)).convert("RGB")), a), (enc, name, level)
                alone_rate, _ = busy_rate(1.0)
                rate, per_image = busy_rate(SECONDS, lambda: fn(a, level))
                row = {"image": name, "level": level, "encoder": enc, "seconds": min(times), "bytes": len(data),
                       "seconds_beside_busy_thread": per_image, "busy_thread_share": rate / alone_rate}
                rows.append(row)
                print(f"{name:22s} level {level} {enc:15s} {1000 * min(times):7.1f} ms {len(data) / 2**20:6.2f} MiB | "
                      f"beside a busy thread {1000 * per_image:7.1f} ms, the thread ran {100 * rate / alone_rate:5.1f} %",
                      flush=True)
    Path(out).write_text(json.dumps({
        "machine": {"host": platform.node(), "cpu_count": os.cpu_count(), "load_average": os.getloadavg(),
                    "python": platform.python_version()},
        "images": {n: list(a.shape) for n, a in images.items()}, "rows": rows,
        "versions": {"PIL": Image.__version__, "numpy": np.__version__},
    }, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
