"""GLSL sources under rayvr/glsl/, with `#include "path"` and compile errors mapped to file:line.

`#include "layout.glsl"` (from any folder: "../layout.glsl") is the header rayvr/gl/gpu_layout.py
generates: the constants the CPU and the shaders share. `#include NAME` includes the file the
define NAME names (a path under the root, or an absolute path: a plugin's file outside rayvr):
how a shared kernel takes an effect's own part or the camera model's code. `#include NAME or
"path"` falls back to "path" (relative to the including file) where NAME is not defined.

Each file gets a source-string number; `#line` directives around every include make the
driver report (number, line), and `ShaderError` turns that back into `glsl/file.glsl:line`
(Mesa writes `0:12(3): error`, NVIDIA `0(12) : error`). A file is included once per
program, whatever the number of `#include`s naming it.
"""
from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import moderngl

from . import gpu_layout

GLSL_DIR = Path(__file__).resolve().parents[1] / "glsl"
_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*(//.*)?$')
# `#include NAME [or "fallback"]`: the file is the value of define NAME (an effect's part, a camera model)
_INCLUDE_DEFINE = re.compile(r'^\s*#\s*include\s+([A-Za-z_]\w*)(?:\s+or\s+"([^"]+)")?\s*(//.*)?$')
_VERSION = re.compile(r"^\s*#\s*version\b")
# Mesa: "0:12(3): error: ..."   NVIDIA: "0(12) : error C0000: ..."
_LOG_LOCATION = re.compile(r"(?m)^(?:ERROR: )?(\d+)(?::(\d+)\((\d+)\)|\((\d+)\))")


class ShaderError(RuntimeError):
    """A shader failed to load, compile or link; the message names the original file and line."""


@dataclass
class ShaderSource:
    text: str
    files: list[str] = field(default_factory=list)  # source-string number -> file name

    def map_log(self, log: str) -> str:
        def where(m: re.Match) -> str:
            idx = int(m.group(1))
            line = m.group(2) or m.group(4)
            name = display_name(self.files[idx]) if idx < len(self.files) else f"<source {idx}>"
            return f"{name}:{line}"
        return _LOG_LOCATION.sub(where, log)


def display_name(name: str) -> str:
    """How messages name a shader file: glsl/<path> under a root, an absolute path as it is."""
    return name if os.path.isabs(name) else f"glsl/{name}"


# Sources generated from Python rather than read from disk.
GENERATED = {"layout.glsl": gpu_layout.glsl_header}


def _read(name: str, root: Path) -> list[str]:
    """The lines of a file under `root`, else under rayvr/glsl/ (so shaders outside rayvr, such as
    an effect plugin's, can include rayvr's common code), else of a generated source."""
    if name in GENERATED:
        return GENERATED[name]().splitlines()
    path = _find(name, root)
    if path is None:
        raise ShaderError(f"shader file not found: {(root / name).resolve()}")
    stat = path.stat()
    return _lines(path, stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=1024)
def _lines(path: Path, mtime_ns: int, size: int) -> list[str]:
    """A file's lines, read once per version of it (a renderer builds hundreds of programs from a
    few dozen files; an edited file has another mtime or size and is read again). Callers never
    modify them."""
    return path.read_text().splitlines()


_FOUND: dict = {}  # (name, root) -> the file found (a missing file is looked for again)


def _find(name: str, root: Path) -> Path | None:
    """The file `name` names: under `root`, else under rayvr/glsl/; an absolute name is itself."""
    found = _FOUND.get((name, root))
    if found is not None and found.is_file():
        return found
    for base in dict.fromkeys((root, GLSL_DIR)):
        path = (base / name).resolve()
        if path.is_file():
            _FOUND[(name, root)] = path
            return path
    return None


def load_source(name: str, defines: dict | None = None, root: Path = GLSL_DIR) -> ShaderSource:
    """Resolve includes of `name` (relative to glsl/) and put `defines` after its #version."""
    files: list[str] = []
    out: list[str] = []
    included = {name}

    def emit(file: str, is_top: bool) -> None:
        idx = len(files)
        files.append(file)
        if not is_top:
            out.append(f"#line 1 {idx}")
        lines = _read(file, root)
        # Defines go right after #version, so that #if blocks around #extension lines see them.
        version = [n for n, line in enumerate(lines, 1) if _VERSION.match(line)] if is_top else []
        header_end = version[0] if version else -1
        for lineno, line in enumerate(lines, start=1):
            m = "include" in line and (_INCLUDE.match(line) or _INCLUDE_DEFINE.match(line))
            where = m and f"{display_name(file)}:{lineno}"  # for an error's message
            if m and m.re is _INCLUDE_DEFINE:
                named, fallback = m.group(1), m.group(2)
                if named in (defines or {}):
                    child = os.path.normpath(str(defines[named]))
                    asked = f"#include {named} ({named} = {defines[named]})"
                elif fallback:
                    child = os.path.normpath(os.path.join(os.path.dirname(file), fallback))
                    asked = f'#include {named} or "{fallback}" ({named} not defined)'
                else:
                    raise ShaderError(f"{where}: #include {named} needs the define {named} "
                                      f"(the path of the file to include)")
            elif m:
                child = os.path.normpath(os.path.join(os.path.dirname(file), m.group(1)))
                asked = f'#include "{m.group(1)}"'
            if m:
                if child not in included:  # once per program; this also stops cycles
                    included.add(child)
                    if child not in GENERATED and _find(child, root) is None:
                        raise ShaderError(f"{where}: {asked}: shader file not found: {(root / child).resolve()}")
                    emit(child, False)
                    out.append(f"#line {lineno + 1} {idx}")
                else:
                    out.append("")
                continue
            out.append(line)
            if lineno == header_end:
                out.extend(f"#define {k} {_define_value(v)}" for k, v in (defines or {}).items())
                out.append(f"#line {lineno + 1} {idx}")

    emit(name, True)
    text = "\n".join(out) + "\n"
    if not text.lstrip().startswith("#version"):
        raise ShaderError(f"{display_name(name)}: the first line must be a #version directive")
    return ShaderSource(text, files)


def _define_value(value) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    return str(value)


def _wrap(sources: dict[str, ShaderSource], fn):
    try:
        return fn()
    except moderngl.Error as exc:
        msg = str(exc)
        for stage, src in sources.items():
            msg = src.map_log(msg) if src else msg
        names = ", ".join(f"{stage}={display_name(s.files[0])}" for stage, s in sources.items() if s)
        raise ShaderError(f"shader build failed ({names}):\n{msg}") from None


def program(ctx: moderngl.Context, vertex: str, fragment: str | None = None,
            geometry: str | None = None, defines: dict | None = None, root: Path = GLSL_DIR) -> moderngl.Program:
    """Build a raster program from files under glsl/."""
    sources = {"vertex": load_source(vertex, defines, root)}
    if fragment:
        sources["fragment"] = load_source(fragment, defines, root)
    if geometry:
        sources["geometry"] = load_source(geometry, defines, root)
    return _wrap(sources, lambda: ctx.program(
        vertex_shader=sources["vertex"].text,
        fragment_shader=sources["fragment"].text if fragment else None,
        geometry_shader=sources["geometry"].text if geometry else None,
    ))


def declares(program, name: str) -> bool:
    """Whether `program` has the uniform (or block) `name`: GLSL compilers drop what a shader does not
    use, so passes set only what it declares. One dict lookup: moderngl programs define no
    `__contains__`, so `name in program` walks every member, a cost paid per uniform per pass per
    MSAA round while the CPU records a frame (foveated 4x frames are that recording's:
    docs/results.md)."""
    return program.get(name, None) is not None


def compute(ctx: moderngl.Context, name: str, defines: dict | None = None,
            root: Path = GLSL_DIR) -> moderngl.ComputeShader:
    """Build a compute shader from a file under glsl/."""
    src = load_source(name, defines, root)
    return _wrap({"compute": src}, lambda: ctx.compute_shader(src.text))
