"""Whether rendering lets other Python threads (the capture's writers) run: while the renderer
makes FRAMES frames of the built-in room, a pure-Python thread ticks (1 ms sleeps), and a profiler
sums the C calls that took over SLOW_S. On llvmpipe a compute dispatch runs inside moderngl's
Program.run, which keeps the GIL.

    python gil_render.py OUT.json [MATERIALS.toml] [WxH]

Run from the repository root.
"""
from __future__ import annotations

import collections
import json
import os
import platform
import sys
import threading
import time
from pathlib import Path

from rayvr.app.capture import poses_for
from rayvr.frame.cameras.rig import StereoRig
from rayvr.renderer import Renderer

FRAMES = 4
STARVED_S = 0.005  # a tick later than this: the ticker was kept from running
SLOW_S = 0.005


def main(out: str, materials: str = "rayvr/assets/raster.toml", size: str = "1440x1600") -> None:
    w, h = map(int, size.split("x"))
    starts, slow = {}, collections.Counter()

    def profile(frame, event, arg):
        if event == "c_call":
            starts[id(frame)] = time.perf_counter()
        elif event in ("c_return", "c_exception") and id(frame) in starts:
            took = time.perf_counter() - starts.pop(id(frame))
            if took > SLOW_S:
                slow[getattr(arg, "__qualname__", str(arg))] += took

    stop, starved = threading.Event(), [0.0]

    def tick():
        last = time.perf_counter()
        while not stop.is_set():
            time.sleep(0.001)
            now = time.perf_counter()
            if now - last > STARVED_S:
                starved[0] += now - last
            last = now

    with Renderer(None, materials) as r:
        rig = StereoRig.for_scene(r.scene, size=(w, h))
        rigs = [StereoRig(**{**rig.__dict__, "pose": p}) for p in poses_for(rig, r.scene, frames=FRAMES)]
        next(iter(r.render_sequence(rigs[:1])))  # compiled and warm
        ticker = threading.Thread(target=tick)
        ticker.start()
        sys.setprofile(profile)
        start = time.perf_counter()
        for _ in r.render_sequence(rigs):
            pass
        wall = time.perf_counter() - start
        sys.setprofile(None)
        stop.set()
        ticker.join()
        gl = r.gl.info()["renderer"]
    result = {"machine": {"host": platform.node(), "cpu_count": os.cpu_count(), "gl": gl,
                          "load_average": os.getloadavg()},
              "materials": materials, "size": [w, h], "eyes": 2, "frames": FRAMES, "wall_s": wall,
              "ticker_starved_share": starved[0] / wall,
              "slow_c_calls_s": dict(slow.most_common(5))}
    print(json.dumps(result, indent=1))
    Path(out).write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
