"""Constants the shaders share with Python are declared once, in Python (rayvr/gl/glsl_constants.py
declare, emitted in the generated layout.glsl), and never typed into a shader by hand."""
import importlib
import pkgutil
import re

import numpy as np
import pytest

import rayvr
from rayvr.gl import glsl_constants, gpu_layout
from rayvr.gl.glsl_constants import declare, literal
from rayvr.gl.shaders import GLSL_DIR

# A number, or arithmetic of numbers: `64`, `0xFFFFFFFFu`, `1e-4`, `(1.0 / 256.0)`, `-1.0`.
_NUMBER = r"[-+]?(?:0[xX][0-9a-fA-F]+|\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)[uUfF]?"
_NUMERIC = re.compile(rf"[\s(]*{_NUMBER}[\s)]*(?:[-+*/][\s(]*{_NUMBER}[\s)]*)*")
_DEFINE = re.compile(r"^\s*#\s*define\s+(\w+)\s+(.*?)\s*(?://.*)?$")
_CONST = re.compile(r"^\s*const\s+\w+\s+(\w+)\s*=\s*(.*?)\s*;")
_CONDITIONAL = re.compile(r"^\s*#\s*(if|ifdef|ifndef|else|elif|endif)\b\s*(\w*)")

# Numeric defines and consts that no Python module declares, each with why it lives in the shader.
SHADER_LOCAL = {
    "PI": "math", "QUARTER_PI": "math", "golden": "math (the golden-ratio sequence of shadow_rays.glsl)",
    "big": "tile_cull.comp's reduction identity",
    "BVH_MARGIN": "the wide traversal's box slack for quantized boxes",
    "TILE_CULL_WRITER": "a switch of tile_cull.comp", "TILE_SUBRAYS": "tile_cull.comp: sub-rays per sample",
    "TILE_MEAN_RAYS": "tile_cull.comp: rays averaged per sample",
    "PIXEL_RAYS": "tile_samples.comp: the sub-rays an invocation tests (1 outside the MSAA trace)",
    "RAY_BLOCKS": "tile_samples.comp: blocks of sub-rays with a map each (1 outside the MSAA trace)",
    "SECOND_LAYER_SKIPS": "second_layer.comp's bound on skipped hits", "est_k": "a local of estimate.glsl",
    "KD_STACK": "the kd-tree walk's stack (> the depth of any tree rayvr builds)",
    "SORT_CHUNK": "radix_sort.comp's shared-memory histogram chunk",
    "DISOCCLUSION_DEPTH": "accumulate.comp's history test", "APRON": "denoise.comp's taps per stage",
    "OUTSIDE": "denoise.comp: the effect of a tap outside the image",
    "LOG2_E": "math (denoise.comp's weights as one exp2)", "NO_WEIGHT": "denoise.comp: log2 of a zero weight",
    "RT_MAX_GROUPS_X": "GL's minimum of the most work groups in x",
    "WAVE_IDLE": "wave.glsl: a path without a ray this bounce", "RT_SLOT": "wave_shade.comp's list",
    "FILLED": "cameras/foveated_resolve.glsl: the weight of a filled point",
    "MASK_NONE": "sub_mask.glsl: the empty sub-ray mask", "MASK_WORDS": "sub_mask.glsl: words a sub-ray mask takes",
}


def import_every_module() -> list:
    """Every rayvr module (a module's declarations reach the header once it is imported)."""
    mods = []
    for info in pkgutil.walk_packages(rayvr.__path__, "rayvr."):
        if info.name.endswith("__main__"):  # runs the CLI
            continue
        try:
            mods.append(importlib.import_module(info.name))
        except ImportError as exc:  # an optional dependency (ray, glfw, ...) that this machine lacks
            if (exc.name or "").startswith("rayvr"):
                raise
    return mods


def _python_numbers(mods) -> dict:
    """{NAME: value} of the module-level int and float constants of every rayvr module."""
    out = {}
    for mod in mods:
        for name, value in vars(mod).items():
            if name.isupper() and isinstance(value, (int, float, np.integer, np.floating)) \
                    and not isinstance(value, bool):
                out.setdefault(name, set()).add(float(value))
    return out


def _numeric_definitions():
    """(file, line, name, value text, whether it is the default of a define a pass sets) of every
    `#define NAME <number>` and `const T NAME = <number>;` in the shipped shaders."""
    for path in sorted(GLSL_DIR.rglob("*")):
        if not path.is_file():
            continue
        open_blocks = []  # the guard name of each enclosing #ifndef, '' for other conditionals
        for n, line in enumerate(path.read_text().splitlines(), 1):
            c = _CONDITIONAL.match(line)
            if c:
                if c.group(1) in ("if", "ifdef", "ifndef"):
                    open_blocks.append(c.group(2) if c.group(1) == "ifndef" else "")
                elif c.group(1) == "endif":
                    open_blocks.pop()
                continue
            m = _DEFINE.match(line) or _CONST.match(line)
            if m and _NUMERIC.fullmatch(m.group(2)):
                guard = open_blocks[-1] if open_blocks else ""
                default = bool(guard) and not guard.endswith("_GLSL")  # not an include guard
                yield path.relative_to(GLSL_DIR), n, m.group(1), m.group(2), default


def _value(text: str) -> float:
    return float(eval(re.sub(r"(?<=[0-9a-fA-F.])[uUfF]\b", "", text)))  # the shader's arithmetic of literals


def test_no_python_constant_is_typed_into_a_shader():
    """A numeric define whose name (less one prefix, as QT_ or SSR_) names a rayvr constant of the same
    value is a hand copy; one the header emits is a copy too; any other must be a define a pass sets
    (its default under #ifndef) or listed in SHADER_LOCAL with a reason."""
    numbers = _python_numbers(import_every_module())
    copies, unlisted = [], []
    for file, line, name, text, default in _numeric_definitions():
        where = f"glsl/{file}:{line} {name} {text}"
        candidates = {name.upper(), name.upper().split("_", 1)[-1]}
        if name in glsl_constants.CONSTANTS or any(_value(text) in numbers.get(c, ()) for c in candidates):
            copies.append(where)
        elif not default and name not in SHADER_LOCAL:
            unlisted.append(where)
    assert not copies, "shader constants typed by hand; declare them in Python instead:\n" + "\n".join(copies)
    assert not unlisted, "numeric shader defines no Python module declares (declare them, or list them " \
                         "in SHADER_LOCAL with a reason):\n" + "\n".join(unlisted)


def test_work_group_sizes_are_named():
    """The Python side dispatches by a shader's work group size, so a size is a declared constant (or a
    define a pass sets), never a literal (1, a single invocation, is no shared size)."""
    literals = [f"glsl/{path.relative_to(GLSL_DIR)}:{n} {line.strip()}"
                for path in sorted(GLSL_DIR.rglob("*.comp"))
                for n, line in enumerate(path.read_text().splitlines(), 1)
                if any(int(v) > 1 for v in re.findall(r"local_size_[xyz]\s*=\s*(\d+)", line))]
    assert not literals, "work group sizes typed by hand:\n" + "\n".join(literals)


def test_the_scan_finds_a_hand_copy():
    """The scan's patterns match the forms the shaders used (so the test above is not vacuous)."""
    for text in ("0.05", "3.814697265625e-06", "0xFFFFFFFFu", "(1.0 / 256.0)", "3.0e38", "-1.0", "1u"):
        assert _NUMERIC.fullmatch(text), text
    assert _value("(1.0 / 256.0)") == 2.0 ** -8 and _value("0x80000000u") == 2.0 ** 31
    for text in ("SSRT_HIT", "vec3(1.0)", "rgba16f", "(BVH_WIDTH / 4)"):
        assert not _NUMERIC.fullmatch(text), text


def test_shared_constants_reach_the_header_exactly():
    """The constants the issue found copied by hand come from their Python owners, value for value."""
    import_every_module()
    from rayvr.accel import gpu, quadtree
    from rayvr.bench.tracers import dda, hiz
    from rayvr.frame.cameras import CAMERA_MODELS
    from rayvr.frame.passes import prefix_scan as photon_scan
    from rayvr.frame.passes import reuse, warp

    header = {m.group(1): m.group(2) for m in re.finditer(r"(?m)^#define (\w+) (.*)$", gpu_layout.glsl_header())}
    expected = {"SSRT_HIT": "1u", "SSRT_NONE": "4u", "SSRT_OCCLUDED": "5u", "QT_ON_LEAF": "3.814697265625e-06",
                "QT_AABB_MARGIN": "9.5367431640625e-07", "QT_PLANE_BIT": "0x80000000u", "HIZ_EMPTY": "3e+38",
                "DDA_EDGE": "0.00390625", "BVH_BINARY_STACK_SIZE": "64", "BVH_MISS": "0xFFFFFFFFu",
                "SCAN_BLOCK": "1024", "RECT_LIGHT_GRID": "4",
                "REUSE_NONE": "0xFFFFFFFFu", "WARP_COUNTS": "6", "WARP_COUNT_NODES": "5u"}
    assert {k: header.get(k) for k in expected} == expected
    # the values are the owners' (one declaration: dda and hiz take the quadtree's statuses)
    assert (dda.HIT, hiz.NONE, quadtree.OCCLUDED) == (1, 4, 5) and dda.NONE is quadtree.NONE
    assert float(header["QT_ON_LEAF"]) == quadtree.ON_LEAF == 2.0 ** -18
    assert np.float32(header["HIZ_EMPTY"]) == hiz.EMPTY and np.float32(header["DDA_BIAS"]) == dda.BIAS
    assert int(header["BVH_BINARY_STACK_SIZE"]) == gpu.STACK_SIZE
    assert int(header["SCAN_BLOCK"]) == photon_scan.SCAN_BLOCK == photon_scan.SCAN_GROUP * photon_scan.SCAN_ITEMS
    assert int(header["REUSE_NONE"].rstrip("u"), 16) == reuse.REUSE_NONE
    assert [int(header[f"WARP_COUNT_{k.upper()}"].rstrip("u")) for k in warp.COUNTS] == list(range(len(warp.COUNTS)))
    # the camera ids: each registered model's CAMERA_MODEL value, 1, 2, ... in registration order
    ids = [int(header["CAMERA_" + name.upper()]) for name in CAMERA_MODELS]
    assert ids == list(range(1, len(CAMERA_MODELS) + 1))


@pytest.mark.parametrize("value, text", [
    (64, "64"), (-3, "(-3)"), (0.05, "0.05"), (2.0 ** -20, "9.5367431640625e-07"), (1e-4, "0.0001"),
    (65504.0, "65504.0"), (-1.0, "(-1.0)"), (np.float32(3.0e38), "3e+38"), (np.float32(1 / 256), "0.00390625"),
])
def test_literals_round_trip(value, text):
    """Floats are written so that they read back as the same float (float32 ones as the same float32)."""
    assert literal(value) == text
    back = float(text.strip("()"))
    assert (np.float32(back) == value) if isinstance(value, np.float32) else back == value


def test_uint_literals_and_bad_values():
    assert literal(5, uint=True) == "5u" and literal(0xFFFFFFFF, uint=True) == "0xFFFFFFFFu"
    for bad, uint in ((True, False), (float("inf"), False), (-1, True), (0.5, True), ("4", False)):
        with pytest.raises((TypeError, ValueError)):
            literal(bad, uint)


def test_a_constant_is_declared_once():
    """Declaring a name again with another value is an error (two owners); the same value is allowed."""
    name = "TEST_ONLY_DECLARED_ONCE"
    try:
        assert declare(name, 3) == 3 and declare(name, 3) == 3
        with pytest.raises(ValueError, match=name):
            declare(name, 4)
        assert f"#define {name} 3" in gpu_layout.glsl_header()
    finally:
        glsl_constants.CONSTANTS.pop(name, None)


def _imports(path, module: str) -> set:
    """The rayvr modules `module` (source at `path`) imports, function-level imports included."""
    import ast

    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("rayvr")}
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")
            base = base[:len(base) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            if target.startswith("rayvr"):
                out.add(target)
                out |= {f"{target}.{a.name}" for a in node.names}  # `from . import shaders`
    return out


def test_a_shader_is_compiled_where_its_constants_are_declared():
    """A declared constant reaches the header once its owner is imported, so each module that compiles
    a shader must import (directly or through others) the owner of every declared constant the shader
    uses, or the shader would not build where that module alone is imported."""
    from rayvr.gl.shaders import load_source

    root = GLSL_DIR.parent
    sources = {f"rayvr.{'.'.join(p.relative_to(root).with_suffix('').parts)}".removesuffix(".__init__"): p
               for p in root.rglob("*.py")}
    graph = {m: _imports(p, m) & set(sources) for m, p in sources.items()}

    def closure(m):
        seen, todo = set(), [m, "rayvr"]  # the package's __init__ runs first
        while todo:
            x = todo.pop()
            if x not in seen:
                seen.add(x)
                todo += graph.get(x, ())
        return seen

    declarations = {}  # the name a declare() call spells, or its f-string's fixed start -> module
    for m, p in sources.items():
        for name in re.findall(r'declare\(f?"([A-Z][A-Z0-9_]*)', p.read_text()):
            declarations[name] = m
    import_every_module()
    owner_of = {}  # declared constant -> the module that declares it
    for name in glsl_constants.CONSTANTS:
        owner_of.update({name: m for start, m in declarations.items() if name.startswith(start)})
    assert set(owner_of) >= {"SSRT_HIT", "CAMERA_PINHOLE", "WARP_COUNT_NODES", "PIXEL_TILE"}
    missing = []
    for m, p in sources.items():
        for shader in sorted(set(re.findall(r'"([\w/]+\.(?:comp|vert|frag))"', p.read_text()))):
            if not (GLSL_DIR / shader).is_file():
                continue
            text = "\n".join(line for line in load_source(shader, {"EFFECT_PATHS": "effects/shadows.glsl"}).text
                             .splitlines() if not line.startswith("#define ") or line.split()[1] not in owner_of)
            used = set(re.findall(r"\b[A-Z][A-Z0-9_]*\b", text)) & set(owner_of)
            need = {owner_of[n] for n in used} - closure(m)
            missing += [f"{m} compiles {shader} without importing {o}" for o in sorted(need)]
    assert not missing, "\n".join(missing)
