"""rayvr's modules import each other without cycles, lazy (function-level) imports included, and the
product never imports its benchmarks (docs/architecture.md, "Layers").

The graph is read from the source with `ast`, so an import hidden inside a function counts like one
at the top. What an import statement costs in Python decides its edges:

- `import a.b.c` / `from a.b.c import n`: an edge to a.b.c, and to each package above it that the
  importer is not inside itself (importing `rayvr.frame.effects.ssr` from `rayvr.frame.passes` runs
  `rayvr/frame/effects/__init__.py`; from inside `rayvr.frame.effects` that package is already running).
- `from a.b import n`: also an edge to a.b.n when n is a module (`from . import shaders`).
- `from . import n` / `from .. import n` where n is a module: an edge to that module alone; where n
  is a name: an edge to the package, which is then imported back *for names*: a cycle with its
  `__init__` (a package's `__init__` that imports its own submodules is normal, and makes no cycle
  unless one of them imports the package back).
- Imports under `if TYPE_CHECKING:` never run, and are left out.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "rayvr"
BENCH = "rayvr.bench"
# The product's only doors into its benchmarks: the command line that runs them.
BENCH_USERS = {"rayvr.commands.bench"}
# The layers of docs/architecture.md, lowest first: a module may import its own layer and those
# below, never one above. A module or package is placed by its longest listed prefix; a new module
# must be placed (the test says so).
LAYERS = (
    # the packages: their __init__ imports nothing
    ("rayvr.gl", "rayvr.util", "rayvr.scene", "rayvr.frame", "rayvr.reference", "rayvr.quality", "rayvr.app"),
    ("rayvr.gl.glsl_constants", "rayvr.options", "rayvr.util.digest"),
    ("rayvr.gl.gpu_layout",),
    ("rayvr.frame.effect_registry", "rayvr.frame.cameras", "rayvr.gl.shaders", "rayvr.gl.limits", "rayvr.util.inputs",
     "rayvr.frame.pcg", "rayvr.gl.timing", "rayvr.util.signals", "rayvr.util.extras", "rayvr.util.output",
     "rayvr.frame.cameras.rig", "rayvr.scene.loader", "rayvr.scene.light_selection", "rayvr.scene.surfaces", "rayvr.frame.stereo", "rayvr.gl.context",
     "rayvr.frame.accumulation", "rayvr.render_options"),
    ("rayvr.settings",),  # the render options collected: nothing heavy (test_settings_import_nothing_heavy)
    ("rayvr.accel", "rayvr.frame.gbuffer", "rayvr.frame.graph"),
    ("rayvr.frame.passes",),
    ("rayvr.frame.effects",),
    ("rayvr.scene.materials", "rayvr.scene.defaults", "rayvr.scene.gpu_scene", "rayvr.reference.denoise", "rayvr.reference.shading",
     "rayvr.renderer", "rayvr.frame.readback", "rayvr.app.views", "rayvr.app.viewpoint", "rayvr.app.capture_files",
     "rayvr.app.capture",
     "rayvr.quality.metrics", "rayvr.quality.reference_images", "rayvr.quality.measure", "rayvr.quality.budget",
     "rayvr.quality.frame_knobs", "rayvr.quality.frame_budget", "rayvr.quality.tonemap", "rayvr.quality.metric_pool",
     "rayvr.quality.rungs", "rayvr.quality.motion_error",
     "rayvr.scene.config_toml",
     "rayvr.app.cluster", "rayvr.app.preview", "rayvr.app.hud"),
    (BENCH,),
    ("rayvr.cli", "rayvr.commands", "rayvr.__main__", "rayvr"),
)


def module_sources(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> source file, packages under their own name."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = (root.name,) + path.relative_to(root).with_suffix("").parts
        out[".".join(parts).removesuffix(".__init__")] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _import_nodes(tree: ast.AST):
    """Every Import/ImportFrom under `tree`, function bodies included, TYPE_CHECKING blocks left out."""
    todo = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            todo += node.orelse
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        todo += ast.iter_child_nodes(node)


def named_imports(module: str, path: Path, modules) -> set[str]:
    """The dotted names the import statements of `module` (source `path`) name as modules."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    named = set()
    for node in _import_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            named |= {a.name for a in node.names}
            continue
        if node.level:
            base = package.split(".")[:len(package.split(".")) - node.level + 1]
            target = ".".join(base + ([node.module] if node.module else []))
        else:
            target = node.module
        submodules = {f"{target}.{a.name}" for a in node.names} & set(modules)
        named |= submodules
        if len(submodules) < len(node.names):  # a name, not only submodules: the package itself
            named.add(target)
    return named


def module_imports(module: str, path: Path, modules) -> set[str]:
    """The modules of `modules` that running `module` (source `path`) may import, by the rules above."""
    out = set()
    for name in named_imports(module, path, modules):
        parts = name.split(".")
        for depth in range(1, len(parts) + 1):
            above = ".".join(parts[:depth])
            if above in modules and (depth == len(parts) or not (module + ".").startswith(above + ".")):
                out.add(above)
    out.discard(module)
    return out


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    sources = module_sources(root)
    return {m: module_imports(m, p, sources) for m, p in sources.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's components of more than one module (or a module importing itself), iteratively."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        component.append(m)
                        if m == node:
                            break
                    if len(component) > 1 or node in graph[node]:
                        out.append(sorted(component))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph[child]))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return out


def cycle_path(graph: dict[str, set[str]], component: list[str]) -> list[str]:
    """One readable cycle inside `component`: the shortest path from its first module back to it."""
    inside = set(component)
    start = component[0]
    came_from, frontier = {start: None}, [start]
    while frontier:
        nxt = []
        for node in frontier:
            for child in sorted(graph[node] & inside):
                if child == start:
                    path = [start]
                    while node is not None:
                        path.append(node)
                        node = came_from[node]
                    return path[::-1]  # start, ..., node, start
                if child not in came_from:
                    came_from[child] = node
                    nxt.append(child)
        frontier = nxt
    raise AssertionError(f"no cycle in component {component}")


def describe_cycles(graph) -> list[str]:
    """Each cycle as `N modules: A -> B -> A (also C, D)`, the others of its component after it."""
    out = []
    for component in strongly_connected(graph):
        path = cycle_path(graph, component)
        rest = [m for m in component if m not in path]
        out.append(f"{len(component)} modules: {' -> '.join(path)}" + (f"  (also {', '.join(rest)})" if rest else ""))
    return out


def test_no_import_cycles():
    cycles = describe_cycles(import_graph())
    assert not cycles, "import cycles (lazy imports included):\n" + "\n".join(cycles)


def test_every_import_of_rayvr_names_a_module():
    """A lazy import of a module that moved fails only when its function runs; here, at once."""
    sources = module_sources()
    missing = sorted(f"{m} -> {name}" for m, p in sources.items() for name in named_imports(m, p, sources)
                     if (name + ".").startswith(ROOT.name + ".") and name not in sources)
    assert not missing, "imports of rayvr modules that do not exist:\n" + "\n".join(missing)


def layer_of(module: str) -> int | None:
    """The index in LAYERS of `module`'s longest listed prefix (None: not placed)."""
    placed = [(len(p), i) for i, layer in enumerate(LAYERS) for p in layer
              if module == p or module.startswith(p + ".")]
    return max(placed)[1] if placed else None


def test_imports_go_down_the_layers():
    graph = import_graph()
    unplaced = sorted(m for m in graph if layer_of(m) is None)
    assert not unplaced, "modules in no layer (add them to LAYERS and docs/architecture.md):\n" + "\n".join(unplaced)
    upward = sorted(f"{m} (layer {layer_of(m)}) -> {t} (layer {layer_of(t)})" for m, targets in graph.items()
                    for t in targets if layer_of(t) > layer_of(m))
    assert not upward, "imports of a higher layer:\n" + "\n".join(upward)


def test_the_product_does_not_import_its_benchmarks():
    graph = import_graph()
    bad = sorted(f"{m} -> {t}" for m, targets in graph.items()
                 if not (m + ".").startswith(BENCH + ".") and m not in BENCH_USERS
                 for t in targets if (t + ".").startswith(BENCH + "."))
    assert not bad, "product modules importing rayvr.bench:\n" + "\n".join(bad)


def _graph_of(tmp_path, files: dict[str, str]) -> dict[str, set[str]]:
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    return import_graph(tmp_path / "pkg")


def test_the_graph_reads_every_kind_of_import(tmp_path):
    """The rules of the module docstring on a toy package: lazy, relative, `from . import module`,
    the parent packages an import runs, and TYPE_CHECKING left out."""
    graph = _graph_of(tmp_path, {
        "pkg/__init__.py": "from . import sub\n",
        "pkg/sub/__init__.py": "from .a import A\n",
        "pkg/sub/a.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import c\nA = 1\n",
        "pkg/sub/b.py": "def f():\n    from .. import c\n    from ..sub import a\n",
        "pkg/c.py": "def g():\n    import pkg.sub.a\n",
        "pkg/d.py": "from .sub import A\nfrom pkg import c, d\n",
    })
    assert graph["pkg"] == {"pkg.sub"}
    assert graph["pkg.sub"] == {"pkg.sub.a"}
    assert graph["pkg.sub.a"] == set()                       # TYPE_CHECKING only
    assert graph["pkg.sub.b"] == {"pkg.c", "pkg.sub.a"}     # lazy; pkg.sub runs already
    assert graph["pkg.c"] == {"pkg.sub", "pkg.sub.a"}       # importing pkg.sub.a runs pkg/sub/__init__
    assert graph["pkg.d"] == {"pkg.sub", "pkg.c"}           # modules of pkg, not pkg; d is itself
    assert strongly_connected(graph) == []


def test_cycles_are_found_and_named(tmp_path):
    """A lazy import closing a loop is a cycle, and so is a submodule importing its package back for
    names; the report is a path that returns to where it starts."""
    graph = _graph_of(tmp_path, {
        "pkg/__init__.py": "",
        "pkg/reg/__init__.py": "from .base import register\nfrom . import one\n",
        "pkg/reg/base.py": "def register(x):\n    pass\n",
        "pkg/reg/one.py": "from pkg.reg import register\n",
        "pkg/x.py": "import pkg.y\n",
        "pkg/y.py": "def late():\n    from . import x\n",
    })
    assert strongly_connected(graph) == [["pkg.reg", "pkg.reg.one"], ["pkg.x", "pkg.y"]]
    assert cycle_path(graph, ["pkg.x", "pkg.y"]) == ["pkg.x", "pkg.y", "pkg.x"]
    assert describe_cycles(graph)[0] == "2 modules: pkg.reg -> pkg.reg.one -> pkg.reg"


# Modules that load nothing heavy: a value object and the options' declarations must not pull in the
# GL, the passes, the BVH code or the scene loader (trimesh) with them.
LIGHT = ("rayvr.options", "rayvr.render_options", "rayvr.settings")
HEAVY = ("rayvr.frame", "rayvr.accel", "rayvr.scene", "rayvr.renderer", "rayvr.app", "rayvr.quality", "rayvr.gl.context",
         "rayvr.gl.shaders", "rayvr.gl.timing")


def heavy_reach(graph: dict[str, set[str]], light=LIGHT, heavy=HEAVY) -> list[str]:
    """'light -> ... -> heavy' for every light module that reaches a heavy one, directly or through others."""
    def within(m, prefixes):
        return any(m == p or m.startswith(p + ".") for p in prefixes)

    found = []
    for start in sorted(m for m in graph if within(m, light)):
        seen, stack = {start: None}, [start]
        while stack:
            m = stack.pop()
            for t in sorted(graph.get(m, ())):
                if t in seen:
                    continue
                seen[t] = m
                if within(t, heavy):
                    path = [t]
                    while seen[path[-1]] is not None:
                        path.append(seen[path[-1]])
                    found.append(" -> ".join(reversed(path)))
                    stack.clear()
                    break
                stack.append(t)
    return found


def test_light_modules_reach_no_heavy_one():
    assert heavy_reach(import_graph()) == []


def test_a_light_module_importing_a_heavy_one_is_found(tmp_path):
    graph = _graph_of(tmp_path, {
        "pkg/__init__.py": "", "pkg/light.py": "from . import middle\n", "pkg/middle.py": "def f():\n    from . import heavy\n",
        "pkg/heavy.py": "", "pkg/other.py": "from . import heavy\n"})
    assert heavy_reach(graph, ("pkg.light",), ("pkg.heavy",)) == ["pkg.light -> pkg.middle -> pkg.heavy"]


def test_settings_import_nothing_heavy():
    """`import rayvr.settings` in a fresh interpreter: the declarations and RenderSettings, no GL."""
    import subprocess
    import sys

    code = ("import sys, rayvr.settings as s; s.RenderSettings(msaa=4); "
            "print(' '.join(sorted(m for m in sys.modules if m in ('moderngl', 'trimesh', 'glfw') or "
            "m.startswith(('rayvr.frame', 'rayvr.accel', 'rayvr.scene', 'rayvr.renderer', 'rayvr.gl.context')))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT.parent).stdout
    assert out.strip() == ""
