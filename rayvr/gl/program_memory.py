"""Which arrays of a linked program the driver keeps in local (per-invocation, off-chip) memory.

NVIDIA's program binary (glGetProgramBinary) carries the program's NV_gpu_program5 assembly, where
such an array is declared `TEMP lmemN[size]`. An array the compiler could not keep in registers
costs a memory access per element read: the cwbvh node held as `uvec4 nd[5]` made that traversal
3.5-4.4x slower on the NVIDIA GPU (docs/design.md, cwbvh), and a loop filling TriangleVerts made
photon tracing 2.2x slower. Other drivers' binaries hold no
such text: `local_arrays` then returns None (nothing known), which tests read as "skip"."""
from __future__ import annotations

import ctypes
import re

PROGRAM_BINARY_LENGTH = 0x8741  # GL_PROGRAM_BINARY_LENGTH
_LOCAL_ARRAY = re.compile(r"^TEMP (lmem\d+)\[(\d+)\];", re.M)


def nv_assembly(raw, program) -> str | None:
    """The NV assembly text in `program`'s binary (`raw`: GLContext.raw; `program`: a moderngl
    program or compute shader), or None where the binary holds none."""
    length = ctypes.c_int(0)
    raw.glGetProgramiv(program.glo, PROGRAM_BINARY_LENGTH, ctypes.byref(length))
    if length.value <= 0:
        return None
    data = ctypes.create_string_buffer(length.value)
    written, fmt = ctypes.c_int(0), ctypes.c_uint(0)
    raw.glGetProgramBinary(program.glo, length.value, ctypes.byref(written), ctypes.byref(fmt), data)
    blob = data.raw[:written.value]
    start = blob.find(b"!!NV")
    if start < 0:
        return None
    end = blob.find(b"\0", start)
    return blob[start:end if end >= 0 else None].decode("latin-1")


def local_arrays(raw, program) -> dict[str, int] | None:
    """{array: 4-component slots} the program keeps in local memory (empty: none), or None where
    the driver does not say (not NVIDIA)."""
    text = nv_assembly(raw, program)
    if text is None:
        return None
    return {name: int(size) for name, size in _LOCAL_ARRAY.findall(text)}
