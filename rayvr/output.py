"""Writing results: every file goes through a temporary file in the same folder and
`os.replace`, so an interrupted run never leaves a half-written image or array. The temporary
file is created with mode 0666 and the kernel applies the umask (and any default ACL), so results
get the permissions a plain open() would give them (tempfile.mkstemp's are always 0600)."""
from __future__ import annotations

import io
import os
import secrets
import tempfile
from pathlib import Path

import numpy as np


class OutputError(OSError):
    """An output location cannot be written."""


MAX_PREFIX_BYTES = 200  # file names may have 255 bytes; frame number, eye and channel take the rest


def check_file_prefix(prefix: str) -> str:
    """A file-name prefix that keeps every output inside its folder: not empty, no path separator
    or NUL, no leading '.' ('..', and hidden files a listing would not show). ValueError if not."""
    bad = (not prefix or prefix.startswith(".") or "\0" in prefix or "/" in prefix or "\\" in prefix
           or any(sep and sep in prefix for sep in (os.sep, os.altsep)))
    if bad or len(prefix.encode("utf-8", "surrogateescape")) > MAX_PREFIX_BYTES:
        raise ValueError(f"file prefix must be a plain name of 1 to {MAX_PREFIX_BYTES} bytes: no '/', '\\' or NUL, "
                         f"not starting with '.'; got {prefix[:60]!r}")
    return prefix


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


def check_output_dir(path: str | Path) -> Path:
    """Check, before any work, that `path` is a writable folder or could be created as one, and
    create nothing: a run that fails before its first file leaves no empty folder behind
    (make_output_dir creates it when the first file is written)."""
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise OutputError(f"{path}: output path exists and is not a folder")
        probe, problem = path, "output folder is not writable"
    else:
        probe = next(p for p in path.absolute().parents if p.exists())  # the root always exists
        if not probe.is_dir():
            raise OutputError(f"{path}: cannot create output folder: {probe} is not a folder")
        problem = f"cannot create output folder: {probe} is not writable"
    try:
        with tempfile.TemporaryFile(dir=probe):  # unnamed where the OS allows; removed at once anyway
            pass
    except OSError as exc:
        raise OutputError(f"{path}: {problem}: {exc.strerror or exc}") from exc
    return path


def make_output_dir(path: str | Path) -> Path:
    """Create the output folder (and its parents) when the first file goes into it."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create output folder: {exc.strerror or exc}") from exc
    return path


def _create_temp(path: Path) -> tuple[int, Path]:
    """A new, exclusively created temporary file next to `path`: (fd, its path)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0) | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name next to {path}")


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    path = Path(path)
    try:
        fd, tmp = _create_temp(path)
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
