"""BVHs kept on disk between runs, for the builds that take seconds (the SBVH: Sponza 5.8 s here).

`load(key)` / `store(key, bvh)` keep one `.npz` per key in `cache_dir()`: the directory
RAYVR_BVH_CACHE names, `off` (or empty) for none, by default `~/.cache/rayvr/bvh` (XDG_CACHE_HOME
respected). The key (accel/scene.py `cache_key`) digests the triangles, the build and every build
parameter, so a file is only ever read back for the very BVH it holds. Files are written atomically
(a temporary file renamed over the name); a file that cannot be read (truncated, another format) is
rebuilt and replaced, and a directory that cannot be written only costs the saving: either is one
log line, never an error.
"""
from __future__ import annotations

import json
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from .bvh import Bvh

log = logging.getLogger(__name__)
ENV = "RAYVR_BVH_CACHE"
FORMAT = 1  # bumped whenever the stored arrays or their meaning change
ARRAYS = ("node_lo", "node_hi", "left", "right", "start", "count", "depth", "prim_ids", "indices")


def cache_dir() -> Path | None:
    """Where BVHs are kept; None when RAYVR_BVH_CACHE is `off` or empty."""
    value = os.environ.get(ENV)
    if value is not None:
        return None if value.strip().lower() in ("", "off") else Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "rayvr" / "bvh"


def _path(key: str) -> Path | None:
    d = cache_dir()
    return None if d is None else d / f"{key}.npz"


def load(key: str, vertices) -> Bvh | None:
    """The BVH stored under `key`, over `vertices` (the scene's current positions); None if absent,
    unreadable or of another format."""
    path = _path(key)
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as f:
            if int(f["format"]) != FORMAT:
                raise ValueError(f"format {int(f['format'])}, expected {FORMAT}")
            arrays = {name: f[name] for name in ARRAYS}
            params = json.loads(str(f["params"]))
    except Exception as exc:  # noqa: BLE001 - any unreadable file is rebuilt
        log.warning("BVH cache %s unreadable (%s): building again", path, exc)
        return None
    return Bvh(**arrays, vertices=np.asarray(vertices, np.float32), build_seconds=0.0, params=params)


def store(key: str, bvh: Bvh) -> Path | None:
    """Write `bvh` under `key` (atomically); the file, or None when caching is off or failed."""
    path = _path(key)
    if path is None:
        return None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".bvh-", suffix=".npz")
        try:
            with os.fdopen(fd, "wb") as out:
                np.savez(out, format=np.int64(FORMAT), params=json.dumps(bvh.params),
                         **{name: getattr(bvh, name) for name in ARRAYS})
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError as exc:
        log.warning("BVH cache: cannot write %s (%s); set %s=off to stop trying", path, exc, ENV)
        return None
    return path

