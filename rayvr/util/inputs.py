"""Reading the files a user gives rayvr (views, camera paths, camera sample files, material
configs): each is read whole into memory, so only a regular file up to a size cap is read. A
device (/dev/zero reads for ever), a FIFO (it blocks) or a folder is refused, and so is a file
over the cap, before anything is read. Errors are one line naming the file and what it is for."""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

MAX_IMAGE_SIDE = 16384  # pixels: the largest image width or height rayvr takes (--size, sample files)
MAX_JSON_BYTES = 256 << 20  # a views file or camera path: a million views or poses of ~200 bytes each


class InputFileError(ValueError):
    """An input file that is missing, not a regular file, too large, not UTF-8 text or not JSON."""


def _amount(n: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if n >= 1 << shift:
            return f"{n / (1 << shift):.4g} {unit}"
    return f"{n} bytes"


def read_bytes(path: str | Path, what: str, max_bytes: int) -> bytes:
    """The bytes of the regular file `path`, at most `max_bytes`; `what` names it in the errors."""
    path = Path(path)
    too_big = f"{path}: {what} is larger than {_amount(max_bytes)}, the most rayvr reads"
    try:
        # O_NONBLOCK: opening a FIFO for reading would wait for a writer (a regular file ignores it)
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)  # of what was opened: a check of the path could see another file
        if stat.S_ISDIR(st.st_mode):
            raise InputFileError(f"{path}: {what} is a folder, not a file")
        if not stat.S_ISREG(st.st_mode):
            raise InputFileError(f"{path}: {what} is not a regular file (a device, pipe or socket)")
        if st.st_size > max_bytes:
            raise InputFileError(f"{too_big} (the file has {st.st_size:,} bytes)")
        fh = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with fh:
        try:
            data = fh.read(max_bytes + 1)  # never more, should the file grow meanwhile
        except OSError as exc:
            raise InputFileError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if len(data) > max_bytes:
        raise InputFileError(too_big)
    return data


def read_text(path: str | Path, what: str, max_bytes: int) -> str:
    """read_bytes as UTF-8 text."""
    data = read_bytes(path, what, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{Path(path)}: {what} is not UTF-8 text (byte {exc.start})") from None


def read_json(path: str | Path, what: str, max_bytes: int = MAX_JSON_BYTES):
    """read_text parsed as JSON; nesting too deep for Python's decoder is one error too."""
    text = read_text(path, what, max_bytes)
    try:
        return json.loads(text)
    except RecursionError:  # the decoder recurses once per level of nested arrays and objects
        raise InputFileError(f"{Path(path)}: {what} nested too deeply (arrays or objects hundreds of levels "
                             f"inside each other)") from None
    except ValueError as exc:
        raise InputFileError(f"{Path(path)}: not a {what} (invalid JSON: {exc})") from None
