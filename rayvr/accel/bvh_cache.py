"""BVHs kept on disk between runs, for the builds that take seconds (the SBVH: Sponza 5.8 s here).

`load(key)` / `store(key, bvh)` keep one `.npz` per key in `cache_dir()`: the directory
RAYVR_BVH_CACHE names, `off` (or empty) for none, by default `~/.cache/rayvr/bvh` (XDG_CACHE_HOME
respected). The key (accel/scene.py `cache_key`) digests the triangles, the build and every build
parameter, and a file holds its key and a checksum over its arrays. Files are written atomically
(a temporary file renamed over the name); a file that is not its key's tree (truncated, another
format or key, a checksum that does not match, arrays that are not one consistent tree over the
scene's triangles: check_tree) is rebuilt and replaced, and a directory that cannot be written only
costs the saving: either is one warning line, never an error.
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from .bvh import Bvh

log = logging.getLogger(__name__)
ENV = "RAYVR_BVH_CACHE"
FORMAT = 2  # bumped whenever the stored arrays or their meaning change
TREE_DTYPES = {"node_lo": np.float32, "node_hi": np.float32, "left": np.int32, "right": np.int32,  # as bvh.Bvh
               "start": np.int32, "count": np.int32, "depth": np.int32, "prim_ids": np.uint32, "indices": np.int64}
ARRAYS = tuple(TREE_DTYPES)


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


class Unusable(ValueError):
    """A cache file that is not the tree of its key; the message says why in one phrase."""


def payload_digest(key: str, params: str, arrays: dict) -> str:
    """The checksum a file stores over everything it holds: its key, the build parameters and each
    array's name, dtype, shape and bytes."""
    h = hashlib.blake2b(digest_size=16)
    h.update(json.dumps([key, FORMAT, params]).encode())
    for name in ARRAYS:
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()


def _read(path: Path, key: str) -> tuple[dict, dict]:
    """The arrays and build parameters of a cache file; Unusable if it cannot be read, is of
    another format or key, or its checksum does not match what it holds."""
    try:
        with np.load(path, allow_pickle=False) as f:
            entries = {}
            for name in ("format", "key", "params", "checksum", *ARRAYS):
                if name not in f.files:
                    raise Unusable(f"no array {name!r}")
                try:
                    entries[name] = f[name]
                except ValueError:  # numpy refuses object arrays without unpickling them
                    raise Unusable(f"array {name!r} holds Python objects") from None
    except Unusable:
        raise
    except Exception as exc:  # noqa: BLE001 - a truncated zip, another format, an I/O error...
        raise Unusable(f"unreadable ({type(exc).__name__})") from None
    scalars = {}
    for name in ("format", "key", "params", "checksum"):
        if entries[name].shape != ():
            raise Unusable(f"{name!r} is not a single value")
        scalars[name] = entries[name].item()
    if scalars["format"] != FORMAT:
        raise Unusable(f"format {scalars['format']!r}, expected {FORMAT}")
    if scalars["key"] != key:
        raise Unusable("the tree of another key")
    arrays = {name: entries[name] for name in ARRAYS}
    if not isinstance(scalars["params"], str) or scalars["checksum"] != payload_digest(key, scalars["params"], arrays):
        raise Unusable("its checksum does not match its contents")
    try:
        params = json.loads(scalars["params"])
    except (ValueError, RecursionError):
        raise Unusable("unreadable build parameters") from None
    if not isinstance(params, dict):
        raise Unusable("unreadable build parameters")
    return arrays, params


def check_tree(arrays: dict, params: dict, vertices: np.ndarray, indices: np.ndarray) -> None:
    """Unusable unless the arrays are one consistent tree over these triangles: shapes and dtypes,
    children after their parents (depth-first preorder: no cycles) and within the nodes, leaves
    that tile the reference slots, and each slot's vertex indices those of the scene triangle its
    prim_id names (so the tree is over these very triangles)."""
    a = arrays
    n, t = len(a["left"]), len(a["prim_ids"])
    for name, dtype in TREE_DTYPES.items():
        shape = {"node_lo": (n, 3), "node_hi": (n, 3), "prim_ids": (t,), "indices": (t, 3)}.get(name, (n,))
        if a[name].shape != shape or a[name].dtype != dtype:
            raise Unusable(f"{name!r} is {a[name].dtype}{list(a[name].shape)}, the tree needs {dtype}{list(shape)}")
    if n == 0:
        raise Unusable("no root node")
    if not (np.isfinite(a["node_lo"]).all() and np.isfinite(a["node_hi"]).all()):
        raise Unusable("node boxes that are not finite")
    node = np.arange(n)
    leaf = a["left"] < 0
    if (leaf != (a["right"] < 0)).any():
        raise Unusable("a node with one child")
    inner = ~leaf
    left, right = a["left"][inner].astype(np.int64), a["right"][inner].astype(np.int64)
    if ((left <= node[inner]) | (right <= node[inner]) | (left >= n) | (right >= n)).any():
        raise Unusable("a child index outside the nodes after its parent")
    depth = a["depth"].astype(np.int64)  # sizes the traversal stacks
    if depth[0] != 0 or (depth[left] != depth[inner] + 1).any() or (depth[right] != depth[inner] + 1).any():
        raise Unusable("node depths that are not their parents' plus one")
    if (a["count"][inner] != 0).any() or (a["count"] < 0).any():
        raise Unusable("triangle counts of inner nodes, or negative ones")
    order = np.argsort(a["start"][leaf], kind="stable")
    starts, counts = a["start"][leaf][order].astype(np.int64), a["count"][leaf][order].astype(np.int64)
    if len(starts) and (starts[0] != 0 or (starts[1:] != starts[:-1] + counts[:-1]).any()
                        or starts[-1] + counts[-1] != t):
        raise Unusable("leaves that do not tile the triangle slots")
    triangles = len(indices)
    if params.get("triangles", triangles) != triangles or (a["prim_ids"] >= triangles).any():
        raise Unusable(f"triangle IDs beyond the scene's {triangles} triangles")
    if (a["indices"] < 0).any() or (a["indices"] >= len(vertices)).any():
        raise Unusable(f"vertex indices beyond the scene's {len(vertices)} vertices")
    if not np.array_equal(a["indices"], np.asarray(indices)[a["prim_ids"]]):
        raise Unusable("slots whose vertices are not those of their triangle")


def load(key: str, vertices, indices) -> Bvh | None:
    """The BVH stored under `key`, over the scene's `vertices` (its current positions) and
    triangle `indices`; None if absent, or (with one warning line) unusable: unreadable, of
    another format or key, a checksum that does not match, or arrays that are not one tree over
    these triangles (check_tree)."""
    path = _path(key)
    if path is None or not path.is_file():
        return None
    try:
        arrays, params = _read(path, key)
        check_tree(arrays, params, np.asarray(vertices), np.asarray(indices))
    except Unusable as why:
        log.warning("BVH cache %s: %s; building it again", path, why)
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
                arrays = {name: np.ascontiguousarray(getattr(bvh, name)) for name in ARRAYS}
                params = json.dumps(bvh.params)
                np.savez(out, format=np.int64(FORMAT), key=key, params=params,
                         checksum=payload_digest(key, params, arrays), **arrays)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError as exc:
        log.warning("BVH cache: cannot write %s (%s); set %s=off to stop trying", path, exc, ENV)
        return None
    return path

