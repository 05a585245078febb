"""Writing results: every file goes through a temporary file in the same folder and
`os.replace`, so an interrupted run never leaves a half-written image or array."""
from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np


class OutputError(OSError):
    """An output location cannot be written."""


def ensure_writable_dir(path: str | Path) -> Path:
    """Create `path` if needed and check that files can be written there, before any work."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create output folder: {exc.strerror or exc}") from exc
    if not path.is_dir():
        raise OutputError(f"{path}: output path exists and is not a folder")
    try:
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise OutputError(f"{path}: output folder is not writable: {exc.strerror or exc}") from exc
    return path


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from exc
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write_png(path: str | Path, image: np.ndarray) -> None:
    """uint8 HxW, HxWx3 or HxWx4 (rows top-down) -> PNG."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buf, format="PNG")
    atomic_write_bytes(path, buf.getvalue())


def write_npy(path: str | Path, array: np.ndarray) -> None:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(array))
    atomic_write_bytes(path, buf.getvalue())
