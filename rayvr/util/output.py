"""Writing results: every file goes through a temporary file in the same folder and
`os.replace`, so an interrupted run never leaves a half-written image or array. The temporary
file is created with mode 0666 and the kernel applies the umask (and any default ACL), so results
get the permissions a plain open() would give them (tempfile.mkstemp's are always 0600)."""
from __future__ import annotations

import os
import secrets
import tempfile
from pathlib import Path

import numpy as np

from .png import encode_png


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
    return check_output_dir(make_output_dir(path))


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
    create_output_dir(path)
    return Path(path)


def create_output_dir(path: str | Path) -> list[Path]:
    """Create the output folder and its missing parents; the folders this call created, outermost
    first, so that a job that then writes nothing can remove them again (remove_empty_dirs)."""
    path = Path(path)
    created = []
    for d in reversed([path, *path.parents]):
        if d.is_dir():
            continue
        try:
            d.mkdir()
            created.append(d)
        except FileExistsError:  # made by someone else meanwhile, or a file (the next mkdir says so)
            continue
        except OSError as exc:
            remove_empty_dirs(created)
            raise OutputError(f"{path}: cannot create output folder: {exc.strerror or exc}") from exc
    if not path.is_dir():
        remove_empty_dirs(created)
        raise OutputError(f"{path}: output path exists and is not a folder")
    return created


def remove_empty_dirs(created: list[Path]) -> None:
    """Remove the folders create_output_dir made, innermost first, as long as they are empty."""
    for d in reversed(created):
        try:
            d.rmdir()
        except OSError:  # not empty (someone else's files), or gone
            return


def check_output_files(paths) -> None:
    """Before any work: no file the job writes may have its name taken by a folder (os.replace
    cannot put a file there, and would fail only after the rendering)."""
    for p in paths:
        if Path(p).is_dir():
            raise OutputError(f"{p}: an output file's name is taken by a folder")


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


def _atomic_write(path: Path, fill) -> None:
    """Create a temporary file next to `path`, let `fill(fd, tmp)` write it (closing fd), then
    rename it over `path`; on any failure (Ctrl-C too) the temporary file is removed."""
    try:
        fd, tmp = _create_temp(path)
    except OSError as exc:
        raise _write_error(path, exc) from exc
    try:
        fill(fd, tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):  # disk full (ENOSPC, EFBIG), I/O error
            raise _write_error(path, exc) from exc
        raise


def _write_error(path: Path, exc: OSError) -> OutputError:
    """One line naming the file, keeping the errno (ENOSPC, EFBIG, ...) for callers that check it."""
    error = OutputError(f"{path}: cannot write: {exc.strerror or exc}")
    error.errno = exc.errno
    return error


def atomic_write_bytes(path: str | Path, data: bytes | list) -> None:
    """`data` (bytes, or a list of byte strings written one after another) as the file `path`."""
    def fill(fd, tmp):
        with os.fdopen(fd, "wb") as fh:
            for piece in [data] if isinstance(data, (bytes, bytearray, memoryview)) else data:
                fh.write(piece)

    _atomic_write(Path(path), fill)


def write_png(path: str | Path, image: np.ndarray, compression: int | None = None) -> None:
    """uint8 HxW, HxWx3 or HxWx4 (rows top-down) -> PNG at zlib level `compression` (0..9; None:
    6), encoded without holding the GIL for long (util/png.py)."""
    atomic_write_bytes(path, encode_png(image, compression))


def write_npy(path: str | Path, array: np.ndarray) -> None:
    """The array as .npy, written straight into the file (no copy in memory first)."""
    def fill(fd, tmp):
        with os.fdopen(fd, "wb") as fh:
            np.save(fh, np.ascontiguousarray(array))

    _atomic_write(Path(path), fill)


# capture: png = colour PNG + aux NPY; exr = also HDR colour EXR, float aux as EXR; npy = colour and aux as NPY
FORMATS = ("png", "exr", "npy")
EXR_EXTRA = "pip install 'rayvr[exr]'"  # the optional extra that brings the OpenEXR package


def openexr():
    """The OpenEXR module, or one OutputError saying which extra to install."""
    try:
        import OpenEXR
    except ImportError:
        raise OutputError(f"EXR output needs the OpenEXR package: {EXR_EXTRA}") from None
    if not hasattr(OpenEXR, "File"):  # the numpy API arrived in OpenEXR 3.3
        raise OutputError(f"EXR output needs OpenEXR 3.3 or newer: {EXR_EXTRA} --upgrade")
    return OpenEXR


def write_exr(path: str | Path, image: np.ndarray, names: str = "RGB") -> None:
    """Float HxW or HxWxC (rows top-down) -> OpenEXR, float32, ZIP-compressed, one channel per
    letter of `names` (HxW: one letter, e.g. "Z" for depth)."""
    exr = openexr()
    path = Path(path)
    a = np.asarray(image, np.float32)
    a = a[..., None] if a.ndim == 2 else a
    if a.ndim != 3 or a.shape[-1] != len(names):
        raise ValueError(f"{path}: {a.shape} image does not fit EXR channels {names!r}")
    channels = {n: np.ascontiguousarray(a[..., i]) for i, n in enumerate(names)}
    header = {"compression": exr.ZIP_COMPRESSION, "type": exr.scanlineimage}

    def fill(fd, tmp):
        os.close(fd)  # OpenEXR writes by name; the file keeps the mode it was created with
        try:
            with exr.File(header, channels) as f:
                f.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR's I/O errors
            raise OutputError(f"{path}: cannot write EXR: {exc}") from exc

    _atomic_write(path, fill)
