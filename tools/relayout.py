#!/usr/bin/env python3
"""Move rayvr's modules into packages by layer (issue 21), rewriting everything that names them.

    python tools/relayout.py --dry-run     # the plan: moves, new packages, shims, edits per file
    python tools/relayout.py               # do it (git mv + rewrites), then print the summary

LAYOUT below is the proposed layout: {old dotted name: new dotted name} per package, each package
with the reason it exists. The tool

  a. `git mv`s each module or package (a package with its __init__ and everything under it) and
     writes a docstring-only __init__.py for each package the layout creates;
  b. rewrites every import of a moved module in rayvr/, tests/, tools/, bench/results/**/*.py and
     app.py, module- and function-level, read with `ast`: each import's absolute target is
     resolved from the importing module's OLD place and re-emitted from its NEW place, relative
     where it was relative, absolute where it was absolute; a module imported by name
     (`from . import camera`) keeps its bound name (`from .frame.cameras import rig as camera`);
  c. rewrites dotted names of moved modules anywhere else in those files and in the docs, README,
     pyproject and shader comments ("rayvr.x.Y" in monkeypatch/mock/logger/importlib strings,
     `rayvr.x` in prose, the console script), and file paths: `rayvr/x.py`, `rayvr/pkg/`, and in
     comments, docstrings and the docs the paths written relative to rayvr/ (`passes/shade.py`)
     or to the file's own folder;
  d. moves `Path(__file__).parent` / `.parents[N]` anchors of moved modules so they still reach the
     same folder (the GLSL root, the assets);
  e. places its new packages in tests/test_import_cycles.py LAYERS (their __init__ imports
     nothing) and writes docs/architecture.md's "Packages" section from LAYOUT's reasons;
  f. keeps the old paths the docs tell users to import (SHIMS: the plugin API of rayvr.frame and
     rayvr.effects) resolving, lazily and with a DeprecationWarning; no shim for internals;
  g. prints what it did. A name whose source is absent is skipped (another branch moved it); a
     top-level module the layout does not place is refused, so a new one gets a decision. Run
     twice, it finds nothing to move and changes nothing.

Resources stay where they are: rayvr/glsl/ (the shader include root, served with the generated
layout.glsl header by the shader loader) and rayvr/assets/ are found by path, not imported.
bench/results/ keeps its recorded notes as written (they describe the code of their commit); only
its scripts are rewritten, so they still run.
"""
from __future__ import annotations

import argparse
import ast
import os
import re
import shutil
import subprocess
import sys
import textwrap
import tokenize
from dataclasses import dataclass, field
from io import StringIO
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Layout:
    package: str
    groups: tuple  # (new package, why it exists, {old dotted name: new dotted name})
    keep: dict  # top-level module or package -> why it stays
    shims: dict  # old dotted name -> what users import from it (docs tell them to)
    resources: tuple = ()  # folders under the package found by path
    python_scope: tuple = ()  # folders and files whose Python is rewritten
    text_globs: tuple = ()  # other text files whose names and paths are rewritten
    exclude: tuple = ()  # paths never rewritten
    # file -> name of a tuple of layers (tuples of dotted names) that must place every module: the
    # layout's new packages (docstring-only, importing nothing) become its lowest layer, and the
    # tuple is written again wrapped to the line length
    layer_lists: dict = field(default_factory=dict)
    # (doc file, heading): a "Packages" section made from the groups' reasons and `keep`, put
    # before that heading (or replaced between its markers on a later layout)
    doc_section: tuple = ()
    order: str = ""  # the one direction the packages import each other in, for that section

    @property
    def renames(self) -> dict:
        return {old: new for _, _, moves in self.groups for old, new in moves.items()}


# The proposed layout. The packages import each other in one direction (docs/architecture.md
# "Layers" holds per module): gl, util <- accel <- frame <- scene <- reference, renderer <- quality
# <- app <- bench <- cli, commands, __main__. frame spans layers 3-7 of that list (its registries
# and cameras up to the readback) and scene 3-7 (the loader low, the materials above the effects):
# a package is a concept, the order between packages is strict. A package's __init__ is a
# docstring (no imports), so importing rayvr.frame.passes.x never runs a graph it did not ask for.
RAYVR = Layout(
    package="rayvr",
    groups=(
        ("rayvr.gl", "The GPU interface, no rendering in it: the numbers the shaders share with Python "
         "(glsl_constants, gpu_layout), the shader loader, the GL context, GPU timers, and the float32 "
         "ranges of what reaches the GPU.", {
             "rayvr.glsl_constants": "rayvr.gl.glsl_constants",
             "rayvr.gpu_layout": "rayvr.gl.gpu_layout",
             "rayvr.shaders": "rayvr.gl.shaders",
             "rayvr.context": "rayvr.gl.context",
             "rayvr.timing": "rayvr.gl.timing",
             "rayvr.limits": "rayvr.gl.limits",
         }),
        ("rayvr.util", "Plain helpers that import nothing from rayvr: the files users give (regular files "
         "under a size cap, one-line errors), results written atomically, signal handlers held for a block, "
         "and the optional packages a command needs, named by the extra that installs them.", {
             "rayvr.inputs": "rayvr.util.inputs",
             "rayvr.output": "rayvr.util.output",
             "rayvr.signals": "rayvr.util.signals",
             "rayvr.extras": "rayvr.util.extras",
         }),
        ("rayvr.scene", "What is rendered: the loaded scene, the material config that picks each material's "
         "effect, and both on the GPU.", {
             "rayvr.scene": "rayvr.scene.loader",
             "rayvr.materials": "rayvr.scene.materials",
             "rayvr.gpu_scene": "rayvr.scene.gpu_scene",
         }),
        ("rayvr.frame", "One frame from a plan: the graph of passes and its resources (G-buffer), the passes, "
         "the effects that add them, the cameras (the stereo rig and the camera models), the stereo modes, "
         "sample accumulation and the readback of the images.", {
             "rayvr.frame": "rayvr.frame.graph",
             "rayvr.gbuffer": "rayvr.frame.gbuffer",
             "rayvr.stereo": "rayvr.frame.stereo",
             "rayvr.accumulation": "rayvr.frame.accumulation",
             "rayvr.pcg": "rayvr.frame.pcg",  # the seeds' hash (host twin of random.glsl), not a reference
             "rayvr.readback": "rayvr.frame.readback",
             "rayvr.passes": "rayvr.frame.passes",
             "rayvr.effects": "rayvr.frame.effects",
             "rayvr.effect_registry": "rayvr.frame.effect_registry",  # fix/imports: effects/base.py, below passes
             "rayvr.cameras": "rayvr.frame.cameras",
             "rayvr.camera": "rayvr.frame.cameras.rig",  # the stereo rig (poses, eyes) beside the models
         }),
        ("rayvr.reference", "The numpy references the GPU's shading and denoiser are tested against "
         "(independent of the shaders).", {
             "rayvr.numpy_shading": "rayvr.reference.shading",
             "rayvr.numpy_denoise": "rayvr.reference.denoise",
         }),
        ("rayvr.quality", "A variant's cost and error: image metrics, the reference settings, one variant "
         "measured, and the choice of effects under a frame budget (--budget-ms).", {
             "rayvr.budget": "rayvr.quality.budget",
             "rayvr.measure": "rayvr.quality.measure",  # fix/imports
             "rayvr.metrics": "rayvr.quality.metrics",  # fix/imports (from bench/)
             "rayvr.reference": "rayvr.quality.reference_images",  # fix/imports (from bench/): the module, not the package
         }),
        ("rayvr.app", "The front ends under the command line: capture (its files, multi-view sources), the "
         "preview and its HUD, and the cluster that spreads captures and sweeps over Ray workers.", {
             "rayvr.capture": "rayvr.app.capture",
             "rayvr.capture_files": "rayvr.app.capture_files",  # fix/imports
             "rayvr.views": "rayvr.app.views",
             "rayvr.preview": "rayvr.app.preview",
             "rayvr.hud": "rayvr.app.hud",
             "rayvr.cluster": "rayvr.app.cluster",
         }),
    ),
    keep={
        "rayvr": "the public API: Renderer, RenderSettings, Frame, StereoRig, Pose, EyeView, load, Scene, ...",
        "rayvr.__main__": "python -m rayvr",
        "rayvr.cli": "the top layer with __main__: the command line, the one door into the benchmarks (bench imports "
                     "app.cluster, so the command line cannot sit in app/ without a package cycle)",
        "rayvr.commands": "the command line's commands, beside cli.py for the same reason",
        "rayvr.renderer": "the Renderer puts scene, accel and frame together: the API's entry point, above them",
        "rayvr.settings": "RenderSettings, one field per render option, beside the Renderer that takes it",
        "rayvr.options": "the render options every layer declares (imports nothing from rayvr)",
        "rayvr.accel": "acceleration structures",
        "rayvr.bench": "the benchmarks, reached only through the command line",
    },
    shims={
        "rayvr.frame": "docs/architecture.md 'Add a pass': from rayvr.frame import Pass, Texture, read, write",
        "rayvr.effects": "docs/architecture.md 'Add an effect': from rayvr.effects import Effect, Param, register",
    },
    resources=("glsl", "assets"),
    python_scope=("rayvr", "tests", "tools", "bench/results", "app.py"),
    text_globs=("README.md", "docs/*.md", "pyproject.toml", ".ci/*", "rayvr/**/*.glsl", "rayvr/**/*.comp",
                "rayvr/**/*.vert", "rayvr/**/*.frag", "rayvr/**/*.geom", "rayvr/**/*.toml",
                "tests/**/*.comp", "tests/**/*.glsl"),
    exclude=("tools/relayout.py", "tests/test_relayout.py"),
    layer_lists={"tests/test_import_cycles.py": "LAYERS"},
    doc_section=("docs/architecture.md", "## Layers: who may import whom"),
    order="gl, util <- accel <- frame <- scene <- reference, renderer <- quality <- app <- bench <- cli",
)


class RelayoutError(Exception):
    """The layout cannot be applied as asked (one line: what and where)."""


# ---------------------------------------------------------------------------------------------
# The tree as it is


@dataclass
class Tree:
    root: Path
    package: str
    modules: dict  # dotted name -> path relative to root (packages: their __init__.py)
    packages: set  # dotted names that are packages

    @classmethod
    def read(cls, root: Path, package: str) -> "Tree":
        modules, packages = {}, set()
        base = root / package
        if not (base / "__init__.py").is_file():
            raise RelayoutError(f"{base}: not a Python package (no __init__.py)")
        for path in sorted(base.rglob("*.py")):
            if "__pycache__" in path.parts or not (path.parent / "__init__.py").is_file():
                continue
            rel = path.relative_to(root)
            parts = list(rel.with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
                packages.add(".".join(parts))
            modules[".".join(parts)] = rel
        return cls(root, package, modules, packages)

    def kind(self, name: str) -> str | None:
        return "package" if name in self.packages else "module" if name in self.modules else None


def rename_with(renames: dict, name: str) -> str:
    """`name` (a module or a name in one) after the moves: its longest moved prefix replaced."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        prefix = ".".join(parts[:k])
        if prefix in renames:
            return renames[prefix] + name[len(prefix):]
    return name


# ---------------------------------------------------------------------------------------------
# The plan


@dataclass
class Move:
    old: str
    new: str
    src: Path  # relative to root: a module file, or a package folder
    dst: Path
    is_package: bool


@dataclass
class Plan:
    layout: Layout
    tree: Tree
    moves: list = field(default_factory=list)
    skipped: list = field(default_factory=list)  # (old, why)
    new_packages: dict = field(default_factory=dict)  # dotted -> docstring
    renames: dict = field(default_factory=dict)
    edits: dict = field(default_factory=dict)  # old rel path -> (new text, counts)
    warnings: list = field(default_factory=list)
    shim_files: dict = field(default_factory=dict)  # new rel path -> text (created or appended to an __init__)

    def new_path(self, rel: Path) -> Path:
        for m in self.moves:
            if m.is_package and rel.is_relative_to(m.src):
                return m.dst / rel.relative_to(m.src)
            if not m.is_package and rel == m.src:
                return m.dst
        return rel

    def new_module(self, name: str) -> str:
        return rename_with(self.renames, name)


def module_file(package_dotted: str, is_package: bool) -> Path:
    path = Path(*package_dotted.split("."))
    return path / "__init__.py" if is_package else path.with_suffix(".py")


def make_plan(root: Path, layout: Layout) -> Plan:
    tree = Tree.read(root, layout.package)
    plan = Plan(layout, tree)
    created = {new.rsplit(".", k)[0] for new in layout.renames.values() for k in range(1, new.count("."))}
    for old, new in layout.renames.items():
        kind = tree.kind(old)
        if kind is None:
            plan.skipped.append((old, "absent"))
            continue
        if kind == "package" and old in created:
            plan.skipped.append((old, "already the layout's package"))
            continue
        if old in layout.shims and tree.kind(new) is not None:
            plan.skipped.append((old, "its compatibility shim"))
            continue
        src = module_file(old, kind == "package")
        src = src.parent if kind == "package" else src
        dst = module_file(new, kind == "package")
        dst = dst.parent if kind == "package" else dst
        plan.moves.append(Move(old, new, src, dst, kind == "package"))
        plan.renames[old] = new
    if not plan.moves:
        return plan
    placed = set(layout.renames) | set(layout.keep)
    top = {name for name in tree.modules if name.count(".") == 1}
    unplaced = sorted(n for n in top - placed if n.split(".")[1] not in layout.resources)
    if unplaced:
        raise RelayoutError("the layout does not place " + ", ".join(unplaced) +
                            f": add each to a group of LAYOUT or to KEEP in {Path(__file__).name}")
    moved_dirs = {m.dst for m in plan.moves if m.is_package}
    for m in plan.moves:
        if (root / m.dst).exists():
            raise RelayoutError(f"{m.dst}: exists already; {m.old} cannot move there")
        parts = m.new.split(".")
        for k in range(2, len(parts)):
            pkg = ".".join(parts[:k])
            folder = Path(*parts[:k])
            if folder in moved_dirs or any(p.dst == folder for p in plan.moves):
                continue
            staying = pkg in tree.packages and pkg not in plan.renames
            if not staying and pkg not in plan.new_packages:
                plan.new_packages[pkg] = next((why for p, why, _ in layout.groups if p == pkg),
                                              f"{pkg} (rayvr's modules in packages by layer).")
    for rel in python_files(root, layout):
        plan.edits[rel] = rewrite_python(plan, rel)
    for rel in text_files(root, layout):
        plan.edits[rel] = rewrite_text(plan, rel)
    if layout.doc_section and (root / layout.doc_section[0]).is_file():
        rel = Path(layout.doc_section[0])
        text, counts = plan.edits.get(rel, (None, {}))
        text = packages_section(plan, text if text is not None else (root / rel).read_text(encoding="utf-8"))
        plan.edits[rel] = (text, {**counts, "section": 1})
    plan.edits = {rel: e for rel, e in plan.edits.items() if e[0] is not None}
    plan.shim_files = make_shims(plan)
    return plan


SECTION_START, SECTION_END = "<!-- relayout: packages -->", "<!-- /relayout -->"


def packages_section(plan: Plan, text: str) -> str:
    """`text` with its "Packages" section (from LAYOUT: each package and why, what stays on top)."""
    layout = plan.layout
    def item(text):
        return textwrap.fill(text, 100, initial_indent="- ", subsequent_indent="  ", break_on_hyphens=False)

    lines = [SECTION_START, "## Packages", "",
             textwrap.fill(f"One package per part of the renderer (`tools/relayout.py` LAYOUT); packages "
                           f"import each other in one direction: {layout.order}. Importing a package runs no "
                           f"other module (its `__init__.py` imports nothing).", 100, break_on_hyphens=False), ""]
    for package, why, moves in layout.groups:
        if any(plan.tree.kind(old) or plan.new_module(old) != old for old in moves):
            lines.append(item(f"`{module_file(package, True).parent.as_posix()}/`: {why}"))
    kept = [(name, why) for name, why in layout.keep.items() if plan.tree.kind(name)]
    for name, why in kept:
        path = module_file(name, plan.tree.kind(name) == "package")
        shown = path.parent.as_posix() + "/" if path.name == "__init__.py" and name != layout.package else \
            path.as_posix()
        lines.append(item(f"`{shown}`: {why}"))
    if layout.resources:
        lines.append(item("resources found by path, not imported: " +
                          ", ".join(f"`{layout.package}/{r}/`" for r in layout.resources)))
    lines += [SECTION_END, ""]
    block = "\n".join(lines)
    if SECTION_START in text and SECTION_END in text:
        start = text.index(SECTION_START)
        end = text.index(SECTION_END) + len(SECTION_END) + 1
        return text[:start] + block + text[end:]
    heading = layout.doc_section[1]
    at = text.find("\n" + heading + "\n")
    return text[:at + 1] + block + "\n" + text[at + 1:] if at >= 0 else text.rstrip("\n") + "\n\n" + block


def python_files(root: Path, layout: Layout):
    for entry in layout.python_scope:
        path = root / entry
        found = [path] if path.is_file() else sorted(path.rglob("*.py")) if path.is_dir() else []
        for p in found:
            rel = p.relative_to(root)
            if "__pycache__" not in rel.parts and rel.as_posix() not in layout.exclude:
                yield rel


def text_files(root: Path, layout: Layout):
    seen = set()
    for pattern in layout.text_globs:
        for p in sorted(root.glob(pattern)):
            rel = p.relative_to(root)
            if p.is_file() and p.suffix != ".py" and rel not in seen and rel.as_posix() not in layout.exclude:
                seen.add(rel)
                yield rel


# ---------------------------------------------------------------------------------------------
# Rewriting one file: edits are (start, end, text) in characters of the old text


class Offsets:
    """(line, UTF-8 byte column) of `ast` -> character offset in the text."""

    def __init__(self, text: str):
        self.text = text
        self.starts = [0] + [m.end() for m in re.finditer("\n", text)]

    def __call__(self, lineno: int, col: int) -> int:
        start = self.starts[lineno - 1]
        end = self.starts[lineno] if lineno < len(self.starts) else len(self.text)
        return start + len(self.text[start:end].encode()[:col].decode())

    def span(self, node) -> tuple:
        return self(node.lineno, node.col_offset), self(node.end_lineno, node.end_col_offset)


def import_nodes(tree: ast.AST):
    return [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]


def relative_module(importer_package: str, target: str) -> str:
    """`target` written relative to `importer_package` ("..accel.gpu", "." for the package itself)."""
    a, b = importer_package.split("."), target.split(".")
    common = 0
    while common < min(len(a), len(b)) and a[common] == b[common]:
        common += 1
    return "." * (len(a) - common + 1) + ".".join(b[common:])


def format_from(module: str, names: list, indent: int, width: int = 120) -> str:
    """`from module import a, b as c` for a statement at column `indent`, wrapped in parentheses
    past `width` with its continuation lines under the first name, as the codebase writes them."""
    items = [n if a is None else f"{n} as {a}" for n, a in names]
    one = f"from {module} import " + ", ".join(items)
    if indent + len(one) <= width:
        return one
    head = f"from {module} import ("
    pad = " " * (indent + len(head))
    lines, current, column = [], head, indent + len(head)
    for i, item in enumerate(items):
        piece = item + (", " if i < len(items) - 1 else ")")
        if current not in (head, pad) and column + len(piece.rstrip()) > width:
            lines.append(current.rstrip())
            current, column = pad, len(pad)
        current += piece
        column += len(piece)
    lines.append(current.rstrip())
    return "\n".join(lines)


def module_name_of(rel: Path, package: str) -> tuple | None:
    """(dotted module name, its package) of a file under the package, else None."""
    if not rel.parts or rel.parts[0] != package:
        return None
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
        return ".".join(parts), ".".join(parts)
    return ".".join(parts), ".".join(parts[:-1])


def rewrite_imports(plan: Plan, rel: Path, text: str, tree: ast.AST, offs: Offsets):
    """Edits of the import statements, and the spans of all of them (left alone by the text pass)."""
    package = plan.layout.package
    old_here = module_name_of(rel, package)
    new_here = module_name_of(plan.new_path(rel), package)
    edits, spans = [], []
    for node in import_nodes(tree):
        start, end = offs.span(node)
        spans.append((start, end))
        if isinstance(node, ast.Import):
            names = [(a.name, a.asname) for a in node.names]
            new = [(plan.new_module(n) if n.startswith(package + ".") else n, a) for n, a in names]
            if new != names:
                items = [n if a is None else f"{n} as {a}" for n, a in new]
                edits.append((start, end, "import " + ", ".join(items)))
            continue
        if node.level:
            if old_here is None:
                continue  # a relative import outside the package: not ours
            base = old_here[1].split(".")
            if node.level - 1 > len(base) - 1:
                plan.warnings.append(f"{rel}:{node.lineno}: relative import above {package}")
                continue
            base = base[:len(base) - node.level + 1]
            target = ".".join(base + ([node.module] if node.module else []))
        else:
            target = node.module or ""
        if target != package and not target.startswith(package + "."):
            continue
        groups = {}  # new module -> [(name, asname)]
        for a in node.names:
            sub = f"{target}.{a.name}"
            if a.name != "*" and sub in plan.tree.modules:
                moved = plan.new_module(sub)
                home, last = moved.rsplit(".", 1)
                bound = a.asname or a.name
                groups.setdefault(home, []).append((last, None if bound == last else bound))
            else:
                groups.setdefault(plan.new_module(target), []).append((a.name, a.asname))
        relative = node.level > 0 and new_here is not None

        def spelled(module):
            return relative_module(new_here[1], module) if relative else module

        old_names = [(a.name, a.asname) for a in node.names]
        if len(groups) == 1:
            (home, names), = groups.items()
            if names == old_names:
                old_spelled = "." * node.level + (node.module or "")
                if spelled(home) != old_spelled:
                    statement = text[start:end]
                    m = re.match(r"from\s+([.\w]+)\s*import\b", statement)
                    if not m or m.group(1) != old_spelled:
                        raise RelayoutError(f"{rel}:{node.lineno}: cannot read this import's module")
                    edits.append((start + m.start(1), start + m.end(1), spelled(home)))
                continue
        if "#" in text[start:end]:
            plan.warnings.append(f"{rel}:{node.lineno}: an import with comments inside was re-emitted without them")
        line_start = offs.starts[node.lineno - 1]
        own_line = text[line_start:start].strip() == ""
        indent = start - line_start
        statements = [format_from(spelled(home), names, indent) for home, names in groups.items()]
        joiner = ("\n" + " " * indent) if own_line else "; "
        edits.append((start, end, joiner.join(statements)))
    return edits, spans


DOTTED = r"(?<![\w.]){pkg}(?:\.\w+)+"
# A path ends at a character that cannot continue it; a full stop ends it unless a word follows
# (`camera.py.` ends a sentence, `x.py.bak` is another file).
_END = r"(?![\w\-/]|\.\w)"
FULL_PATH = r"(?<![\w/.\-]){pkg}/(?:\w+/)*(?:\w+\.py|\w+/?)" + _END
BARE_PATH = r"(?<![\w/.\-])(?:\.\./)*(?:(?:\w+/)*\w+\.py|(?:\w+/)+)" + _END


def dotted_edits(plan: Plan, text: str, skip=()):
    """Edits of dotted names of moved modules (and names in them) outside the spans `skip`."""
    out = []
    for m in re.finditer(DOTTED.format(pkg=re.escape(plan.layout.package)), text):
        if any(s <= m.start() < e for s, e in skip):
            continue
        new = plan.new_module(m.group())
        if new != m.group():
            out.append((m.start(), m.end(), new))
    return out


def moved_path(plan: Plan, target: Path) -> Path | None:
    """The new path (relative to root) of an old module file or package folder, or None if it is neither."""
    tree = plan.tree
    parts = list(target.parts)
    if target.suffix == ".py":
        parts[-1] = target.stem
        is_init = parts[-1] == "__init__"
        name = ".".join(parts[:-1] if is_init else parts)
        if name not in tree.modules or (not is_init and name in tree.packages):
            return None
        return plan.new_path(target)
    name = ".".join(parts)
    if name not in tree.packages:
        return None
    return plan.new_path(target)


def path_edits(plan: Plan, rel: Path, text: str, regions, bare: bool):
    """Edits of file paths naming moved modules in `regions` (character spans of the text): paths
    from the repository (`rayvr/x.py`), and with `bare` those relative to the file's own folder or
    to the package (`passes/shade.py`, `camera.py`, `cameras/`)."""
    package = plan.layout.package
    root_dir = Path(package)
    own_dir = rel.parent if rel.parts[:1] == (package,) and rel.parent != root_dir else None
    new_own_dir = plan.new_path(rel).parent
    out = []
    full = re.compile(FULL_PATH.format(pkg=re.escape(package)))
    bare_re = re.compile(BARE_PATH)
    for lo, hi in regions:
        chunk = text[lo:hi]
        for m in full.finditer(chunk):
            written = m.group()
            is_dir = written.endswith("/")
            new = moved_path(plan, Path(written.rstrip("/")))
            if new is not None and new != Path(written.rstrip("/")):
                out.append((lo + m.start(), lo + m.end(), new.as_posix() + ("/" if is_dir else "")))
        if not bare:
            continue
        for m in bare_re.finditer(chunk):
            written = m.group()
            if written.split("/")[0] == package:
                continue
            is_dir = written.endswith("/")
            stripped = written.rstrip("/")
            candidates = ([("own", own_dir)] if own_dir is not None else []) + [("root", root_dir)]
            for how, base in candidates:
                target = Path(os.path.normpath(base / stripped))
                if target.parts[:1] != (package,):
                    continue
                new = moved_path(plan, target)
                if new is None:
                    continue
                if new != target or (how == "own" and new_own_dir != own_dir):
                    if how == "own":
                        spelled = Path(os.path.relpath(new, new_own_dir))
                        if spelled.as_posix().startswith("..") and not written.startswith(".."):
                            spelled = new.relative_to(root_dir)
                    else:
                        spelled = new.relative_to(root_dir)
                    spelled = spelled.as_posix() + ("/" if is_dir else "")
                    if spelled != written:
                        out.append((lo + m.start(), lo + m.end(), spelled))
                break
    return out


def is_file_path(node) -> bool:
    """Path(__file__), Path(__file__).resolve() or .absolute()."""
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("resolve", "absolute"):
        node = node.func.value
    return (isinstance(node, ast.Call) and len(node.args) == 1 and isinstance(node.args[0], ast.Name)
            and node.args[0].id == "__file__"
            and ((isinstance(node.func, ast.Name) and node.func.id == "Path")
                 or (isinstance(node.func, ast.Attribute) and node.func.attr == "Path")))


def anchor_chain(node):
    """(base, levels) of `Path(__file__)...parent` / `.parents[N]`: levels = folders up from the file."""
    if isinstance(node, ast.Attribute) and node.attr == "parent":
        inner = anchor_chain(node.value)
        if inner:
            return inner[0], inner[1] + 1
        return (node.value, 1) if is_file_path(node.value) else None
    if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) and node.value.attr == "parents" \
            and isinstance(node.slice, ast.Constant) and type(node.slice.value) is int:
        base = node.value.value
        inner = anchor_chain(base)
        if inner:
            return inner[0], inner[1] + node.slice.value + 1
        return (base, node.slice.value + 1) if is_file_path(base) else None
    return None


def anchor_edits(plan: Plan, rel: Path, tree: ast.AST, offs: Offsets):
    new_rel = plan.new_path(rel)
    if new_rel == rel:
        return [], 0
    edits, covered = [], []

    def visit(node):
        chain = anchor_chain(node)
        if chain:
            base, levels = chain
            here, there = plan.tree.root / rel, plan.tree.root / new_rel
            anchor = here.parents[levels - 1]
            if anchor not in there.parents:
                raise RelayoutError(f"{rel}:{node.lineno}: Path(__file__) reaches {anchor}, which is not above "
                                    f"{new_rel}; fix it by hand")
            new_levels = list(there.parents).index(anchor) + 1
            covered.append((node.lineno, node.col_offset, node.end_lineno, node.end_col_offset))
            if new_levels != levels:
                start = offs(base.end_lineno, base.end_col_offset)
                end = offs(node.end_lineno, node.end_col_offset)
                edits.append((start, end, ".parent" if new_levels == 1 else f".parents[{new_levels - 1}]"))
            return
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    loose = sum(1 for n in ast.walk(tree) if isinstance(n, ast.Name) and n.id == "__file__") - len(covered)
    if loose > 0:
        plan.warnings.append(f"{rel}: {loose} use(s) of __file__ not in a Path(__file__).parent chain: check by hand")
    return edits, len(edits)


def comment_and_docstring_regions(text: str, tree: ast.AST, offs: Offsets) -> list:
    regions = []
    for tok in tokenize.generate_tokens(StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            regions.append((offs.starts[tok.start[0] - 1] + tok.start[1], offs.starts[tok.end[0] - 1] + tok.end[1]))
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            regions.append(offs.span(node))
    return regions


def apply_edits(text: str, edits: list, rel: Path, plan: Plan) -> str:
    """The text with `edits` made. Where an edit is followed by a column gap (two spaces or more
    before more text on the line: a table, aligned comments), the gap takes up the change in
    length, so the next column stays where it was (down to two spaces)."""
    out, pos = [], 0
    for start, end, new in sorted(set(edits)):
        if start < pos:
            plan.warnings.append(f"{rel}: overlapping edits at character {start}; kept the first")
            continue
        out.append(text[pos:start])
        out.append(new)
        pos = end
        gap = re.match(r" {2,}(?=\S)", text[end:])
        if gap and "\n" not in new:
            width = max(2, len(gap.group()) - (len(new) - (end - start)))
            out.append(" " * width)
            pos = end + gap.end()
    out.append(text[pos:])
    return "".join(out)


def rewrite_python(plan: Plan, rel: Path):
    text = (plan.tree.root / rel).read_text(encoding="utf-8")
    try:
        tree = ast.parse(text, str(rel))
    except SyntaxError as exc:
        raise RelayoutError(f"{rel}:{exc.lineno}: cannot parse: {exc.msg}") from None
    offs = Offsets(text)
    imports, spans = rewrite_imports(plan, rel, text, tree, offs)
    dotted = dotted_edits(plan, text, skip=spans)
    docs = comment_and_docstring_regions(text, tree, offs)
    paths = path_edits(plan, rel, text, docs, bare=True)  # prose: every spelling of a path
    paths += path_edits(plan, rel, text, [(0, len(text))], bare=False)  # code strings: `rayvr/x.py` only
    anchors, n_anchors = anchor_edits(plan, rel, tree, offs)
    edits = imports + dotted + paths + anchors
    counts = {"imports": len(imports), "names": len(dotted), "paths": len(paths), "__file__": n_anchors}
    if not edits:
        return None, counts
    new = apply_edits(text, edits, rel, plan)
    if rel.as_posix() in plan.layout.layer_lists:
        new = rewrite_layers(plan, rel, new, plan.layout.layer_lists[rel.as_posix()])
    try:
        ast.parse(new, str(rel))
    except SyntaxError as exc:
        raise RelayoutError(f"{rel}:{exc.lineno}: the rewrite does not parse ({exc.msg}): a tool bug") from None
    return new, counts


def rewrite_layers(plan: Plan, rel: Path, text: str, name: str, width: int = 120) -> str:
    """`name = ((...), ...)` in `text` written again: the layout's new packages first (a layer of
    their own: they import nothing), then the layers as they are, each wrapped at `width`."""
    tree = ast.parse(text)
    node = next((n for n in tree.body if isinstance(n, ast.Assign) and len(n.targets) == 1
                 and isinstance(n.targets[0], ast.Name) and n.targets[0].id == name), None)
    if node is None or not isinstance(node.value, ast.Tuple) or \
            not all(isinstance(layer, ast.Tuple) for layer in node.value.elts):
        plan.warnings.append(f"{rel}: no tuple of layers named {name}: place the new packages by hand")
        return text
    layers = []
    for layer in node.value.elts:
        items = []
        for item in layer.elts:
            if isinstance(item, ast.Constant) and isinstance(item.value, str):
                items.append(f'"{item.value}"')
            elif isinstance(item, ast.Name):
                items.append(item.id)
            else:
                plan.warnings.append(f"{rel}:{item.lineno}: {name} holds more than names: place the new packages by hand")
                return text
        layers.append(items)
    listed = {item.strip('"') for layer in layers for item in layer}
    new_packages = [f'"{p}"' for p in plan.new_packages if p not in listed]
    lines = [f"{name} = ("]
    if new_packages:
        lines.append("    # the packages of tools/relayout.py's layout: their __init__ imports nothing")
        layers.insert(0, new_packages)
    for items in layers:
        current = "    ("
        for i, item in enumerate(items):
            piece = item + ("," if i < len(items) - 1 or len(items) == 1 else "")
            if current != "    (" and len(current) + 1 + len(piece) + 2 > width:
                lines.append(current)
                current = "     " + piece
            else:
                current += (" " if current != "    (" else "") + piece
        lines.append(current + "),")
    lines.append(")")
    offs = Offsets(text)
    start, end = offs.span(node)
    return text[:start] + "\n".join(lines) + text[end:]


def rewrite_text(plan: Plan, rel: Path):
    try:
        text = (plan.tree.root / rel).read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return None, {}
    dotted = dotted_edits(plan, text)
    paths = path_edits(plan, rel, text, [(0, len(text))], bare=True)
    edits = dotted + paths
    counts = {"names": len(dotted), "paths": len(paths)}
    return (apply_edits(text, edits, rel, plan) if edits else None), counts


# ---------------------------------------------------------------------------------------------
# Compatibility shims: only the old paths the docs tell users to import


SHIM_CODE = '''

def __getattr__(name):
    """A name of the module that was {old} before rayvr's modules moved into packages by layer, from where it is now,
    with a DeprecationWarning (lazily: importing this {kind} imports nothing)."""
    import importlib
    import pkgutil
    import warnings

    if name.startswith("__") or name in {{m.name for m in pkgutil.iter_modules(globals().get("__path__", []))}}:
        raise AttributeError(f"module {{__name__!r}} has no attribute {{name!r}}")
    value = getattr(importlib.import_module("{new}"), name)
    warnings.warn(f"{old}.{{name}} moved to {new}.{{name}}", DeprecationWarning, stacklevel=2)
    return value
'''


def docstring(*paragraphs: str) -> str:
    body = "\n\n".join(textwrap.fill(p, 100) for p in paragraphs)
    return f'"""{body}\n"""\n' if "\n" in body else f'"""{body}"""\n'


def make_shims(plan: Plan) -> dict:
    out = {}
    for old, why in plan.layout.shims.items():
        if old not in plan.renames:
            continue
        new = plan.renames[old]
        if old in plan.new_packages:  # the old module's name is now a package: its __init__ forwards
            rel = module_file(old, True)
            text = docstring(plan.new_packages[old], f"`{old}` was a module before: its names still resolve here, "
                             f"with a DeprecationWarning ({why}).")
            kind = "package"
        else:
            rel = module_file(old, False)
            text = docstring(f"Moved to {new} (rayvr's modules in packages by layer). Kept for code written against the old path "
                             f"({why}): its names resolve here with a DeprecationWarning.")
            kind = "module"
        out[rel] = text + SHIM_CODE.format(old=old, new=new, kind=kind)
    return out


# ---------------------------------------------------------------------------------------------
# Doing it


def git(root: Path, *args):
    done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True)
    if done.returncode:
        raise RelayoutError(f"git {' '.join(args)}: {done.stderr.strip()}")
    return done.stdout


def tracked(root: Path, rel: Path) -> bool:
    return bool(git(root, "ls-files", "--", rel.as_posix()).strip())


def apply(plan: Plan):
    root = plan.tree.root
    # Packages first: a module moving into a moved package (camera.py -> frame/cameras/rig.py) must
    # not make its folder before the package arrives, or the package would land inside it.
    for m in sorted(plan.moves, key=lambda m: not m.is_package):
        if m.is_package:  # its bytecode would travel with it: a rewrite of the same size within the
            for cache in sorted((root / m.src).rglob("__pycache__")):  # second is not seen as stale
                shutil.rmtree(cache)
        (root / m.dst).parent.mkdir(parents=True, exist_ok=True)
        if tracked(root, m.src):
            git(root, "mv", m.src.as_posix(), m.dst.as_posix())
        else:
            (root / m.src).rename(root / m.dst)
    for rel, (text, _) in plan.edits.items():
        (root / plan.new_path(rel)).write_text(text, encoding="utf-8")
    written = [plan.new_path(rel) for rel in plan.edits]
    for pkg, doc in plan.new_packages.items():
        init = module_file(pkg, True)
        if init not in plan.shim_files:
            (root / init).write_text(docstring(doc), encoding="utf-8")
            written.append(init)
    for rel, text in plan.shim_files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
        written.append(rel)
    git(root, "add", "--", *sorted({p.as_posix() for p in written}))


def summary(plan: Plan, dry_run: bool) -> str:
    lines = [("Plan" if dry_run else "Moved") + f" ({len(plan.moves)} moves):"]
    by_group = {}
    for m in plan.moves:
        by_group.setdefault(next((g for g, _, moves in plan.layout.groups if m.old in moves), "?"), []).append(m)
    for group, why, _ in plan.layout.groups:
        if group in by_group:
            lines.append(f"  {group}/  {why}")
            for m in by_group[group]:
                lines.append(f"    {m.src.as_posix():32} -> {m.dst.as_posix()}")
    for old, why in plan.skipped:
        lines.append(f"  skipped {old}: {why}")
    if plan.new_packages:
        lines.append("New packages: " + ", ".join(plan.new_packages))
    if plan.shim_files:
        lines.append("Compatibility shims: " + ", ".join(p.as_posix() for p in plan.shim_files))
    totals = {}
    for rel, (_, counts) in sorted(plan.edits.items()):
        for k, v in counts.items():
            totals[k] = totals.get(k, 0) + v
        if dry_run:
            lines.append(f"  {rel.as_posix():60} " + " ".join(f"{k} {v}" for k, v in counts.items() if v))
    lines.append(f"Rewrote {len(plan.edits)} files: " + ", ".join(f"{v} {k}" for k, v in totals.items()))
    lines += [f"warning: {w}" for w in plan.warnings]
    return "\n".join(lines)


def main(argv=None, layout: Layout = RAYVR) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dry-run", action="store_true", help="print the plan, change nothing")
    parser.add_argument("--root", type=Path, default=REPO, help="the repository (default: this one)")
    args = parser.parse_args(argv)
    try:
        plan = make_plan(args.root.resolve(), layout)
        if not plan.moves:
            print(f"nothing to move: the layout is in place ({len(plan.skipped)} names already moved or absent)")
            return 0
        if not args.dry_run:
            if git(args.root, "status", "--porcelain", "--untracked-files=no").strip():
                raise RelayoutError("the work tree has uncommitted changes: commit or stash them first")
            try:
                apply(plan)
            except (RelayoutError, OSError) as exc:
                raise RelayoutError(f"{exc} (stopped half-way: `git reset --hard && git clean -fd rayvr` undoes "
                                    "it)") from None
        print(summary(plan, args.dry_run))
    except RelayoutError as exc:
        print(f"relayout: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
