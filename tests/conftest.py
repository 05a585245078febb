"""Shared fixtures. GL tests share one headless context per session (moderngl objects belong to
the context current when they were made; mixing contexts in one process breaks them).
RAYVR_GL_BACKEND=osmesa runs the same tests under OSMesa."""
from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_SCENES = Path(os.environ.get("RAYVR_SCENES") or REPO.parent / "shared" / "scenes")
# No BVH files in the user's cache from tests (accel/bvh_cache.py); the cache's own tests set a folder.
os.environ.setdefault("RAYVR_BVH_CACHE", "off")
# A GL error in a frame quotes the driver's message: which call it refused (context.GLContext.log_errors).
os.environ.setdefault("RAYVR_GL_DEBUG", "1")


@pytest.fixture(scope="session")
def gl():
    from rayvr.gl.context import ContextError, create_context

    try:
        g = create_context(os.environ.get("RAYVR_GL_BACKEND") or None)
    except ContextError as exc:
        pytest.skip(f"no OpenGL 4.3 context: {exc}")
    yield g
    g.release()


@pytest.fixture(scope="module")
def room(gl):
    """A Renderer of the built-in room (a module's own `room` fixture takes its place there)."""
    from rayvr.renderer import Renderer

    with Renderer(None, gl=gl) as r:
        yield r


def camera_rig(r, camera, fov=None, size=(48, 24)):
    """The renderer's scene's stereo rig for `camera` (vertical `fov` or the default); 48 x 24: 3 x 3 frame tiles an eye."""
    from rayvr.frame.cameras.rig import StereoRig

    return StereoRig.for_scene(r.scene, size=size, camera=camera, **({"fov_y": fov} if fov else {}))


@pytest.fixture
def count_poll(monkeypatch):
    """`count_poll(mode)`: how MSAA recording learns its round count from then on (frame/passes/
    primary_rays.py COUNT_POLL, a test hook each frame reads afresh: no program or resource depends
    on it), restored after the test."""
    from rayvr.frame.passes import primary_rays

    def set_poll(mode: str) -> None:
        assert mode in primary_rays.COUNT_POLLS, f"COUNT_POLL is one of {primary_rays.COUNT_POLLS}, not {mode!r}"
        monkeypatch.setattr(primary_rays, "COUNT_POLL", mode)
    return set_poll


@pytest.fixture
def shared_scene():
    """Path to a file under ../shared/scenes, or skip when that folder is absent."""
    def get(rel: str) -> Path:
        p = SHARED_SCENES / rel
        if not p.exists():
            pytest.skip(f"{p} not found: the shared scenes folder is absent")
        return p
    return get


# Tests whose commands measure FLIP (rayvr[bench]) skip one by one where flip-evaluator is absent
# (the GPU host has no wheel of it unless one is carried).
needs_flip = pytest.mark.skipif(importlib.util.find_spec("flip_evaluator") is None,
                                reason="flip-evaluator is an optional extra (pip install 'rayvr[bench]')")


def run_rayvr(*args, timeout=300):
    """`python -m rayvr ARGS` in a child process (the CLI as a user runs it), output captured."""
    return subprocess.run([sys.executable, "-m", "rayvr", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def interrupt_rayvr(args, started, what: str, poll_s: float = 0.01, timeout: float = 120):
    """`python -m rayvr ARGS` in a child process, Ctrl-C'd (SIGINT) once `started()` is true:
    (exit status, stdout, stderr). `what` names what never happened when it fails to start."""
    proc = subprocess.Popen([sys.executable, "-m", "rayvr", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + timeout
        while not started():
            assert proc.poll() is None and time.monotonic() < deadline, what
            time.sleep(poll_s)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=timeout)
    finally:
        proc.kill()
    return proc.returncode, out, err


def quick_bench(bench: str, out, *args, timeout=300) -> dict:
    """`rayvr bench BENCH --quick --out OUT ARGS` must succeed; its BENCH.json."""
    run = run_rayvr("bench", bench, "--quick", "--out", out, *args, timeout=timeout)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads((Path(out) / f"{bench}.json").read_text())


def quad(center, u, v):
    """Two triangles spanning center +- u +- v, front face along cross(u, v)."""
    c, u, v = (np.asarray(x, float) for x in (center, u, v))
    verts = np.array([c - u - v, c + u - v, c + u + v, c - u + v])
    return verts, np.array([[0, 1, 2], [0, 2, 3]])


def merge(*parts):
    """Concatenate (verts, faces) parts; returns verts, faces, per-triangle part index."""
    vs, fs, ids, off = [], [], [], 0
    for i, (v, f) in enumerate(parts):
        vs.append(v)
        fs.append(np.asarray(f) + off)
        ids.append(np.full(len(f), i))
        off += len(v)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(ids)


def fail_writes(monkeypatch, code: int, path_contains: str = "") -> None:
    """Writes through os.fdopen (rayvr/util/output.py's atomic writes) fail with OSError(code), as on a
    full disk, for files whose path contains `path_contains` (every file: "")."""
    real_fdopen = os.fdopen

    class Failing:
        def __init__(self, fh):
            self.fh = fh

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            raise OSError(code, os.strerror(code))

    def fdopen(fd, *args, **kw):
        fh = real_fdopen(fd, *args, **kw)
        return Failing(fh) if path_contains in os.readlink(f"/proc/self/fd/{fd}") else fh

    monkeypatch.setattr(os, "fdopen", fdopen)

