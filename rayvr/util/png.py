"""PNG encoding in one zlib call, which lets go of the GIL for the whole image.

Pillow's PNG encoder hands its output back to Python 64 KiB at a time and takes the GIL for each
piece. Beside a thread that holds the GIL for long (the capture's render thread, recording GL
calls) each piece waits up to the interpreter's switch interval, and a pool of writer threads
saturates the GIL and starves the render thread (docs/capture.md). Here the row filter is one numpy
operation and the compression one `zlib.compress` call: a thread encoding a frame holds the GIL
for a few Python statements. The pixels decode exactly as written (tests/test_png.py, against
Pillow's decoder).
"""
from __future__ import annotations

import struct
import zlib

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"
COLOR_TYPES = {1: 0, 3: 2, 4: 6}  # channels -> PNG colour type: grey, RGB, RGBA
# filter type 1 ("Sub"): each byte minus the same channel of the pixel to its left. On rendered
# frames at zlib level 1 it gives files as small as Pillow's adaptive per-row choice (measured on
# the room and on path-traced noise), and numpy computes it for the whole image in one pass.
SUB_FILTER = 1
DEFAULT_LEVEL = 6  # zlib's and Pillow's default


def _chunk(tag: bytes, data) -> bytes:
    """A chunk's length and tag, for `data` to follow, and its CRC over tag and data."""
    return struct.pack(">I", len(data)) + tag, struct.pack(">I", zlib.crc32(data, zlib.crc32(tag)))


def encode_png(image: np.ndarray, level: int | None = None) -> list:
    """uint8 HxW, HxWx1, HxWx3 or HxWx4 (rows top-down) -> the PNG file as a list of byte strings
    (written one after another; not joined, which would copy the image once more)."""
    a = np.asarray(image)
    if a.dtype != np.uint8:
        raise ValueError(f"PNG encoding takes 8-bit pixels, got {a.dtype}")
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in COLOR_TYPES or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"PNG encoding takes an HxW, HxWx3 or HxWx4 image, got shape {np.shape(image)}")
    h, w, c = a.shape
    flat = a.reshape(h, w * c)
    rows = np.empty((h, 1 + w * c), np.uint8)  # each row: its filter type, then the filtered bytes
    rows[:, 0] = SUB_FILTER
    rows[:, 1:1 + c] = flat[:, :c]
    np.subtract(flat[:, c:], flat[:, :-c], out=rows[:, 1 + c:])  # uint8 wraps around, as PNG's filter does
    header = struct.pack(">IIBBBBB", w, h, 8, COLOR_TYPES[c], 0, 0, 0)  # 8 bits, deflate, adaptive, no interlace
    data = zlib.compress(rows, DEFAULT_LEVEL if level is None else level)
    pieces = [SIGNATURE]
    for tag, body in ((b"IHDR", header), (b"IDAT", data), (b"IEND", b"")):
        head, crc = _chunk(tag, body)
        pieces += [head, body, crc]
    return pieces
