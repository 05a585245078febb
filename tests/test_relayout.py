"""tools/relayout.py on a small synthetic package (not rayvr's layout): every import form it
rewrites, dotted names and paths in strings, comments and docs, `Path(__file__)` anchors, the
compatibility shim, and that it refuses or does nothing where it should."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parents[1] / "tools" / "relayout.py"


def load_tool():
    spec = importlib.util.spec_from_file_location("relayout_tool", TOOL)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


tool = load_tool()

LAYOUT = tool.Layout(
    package="toy",
    groups=(("toy.base", "Plain helpers.", {"toy.util": "toy.base.util"}),
            ("toy.view", "Views and their passes.", {"toy.cam": "toy.view.rig", "toy.passes": "toy.view.passes"}),
            ("toy.scene", "What is shown.", {"toy.scene": "toy.scene.loader", "toy.gone": "toy.base.gone"})),
    keep={"toy.keep": "stays on top"},
    shims={"toy.scene": "docs: from toy.scene import load"},
    resources=("data",),
    python_scope=("toy", "tests"),
    text_globs=("docs/*.md", "toy/**/*.glsl"),
    layer_lists={"tests/layers.py": "LAYERS"},
    doc_section=("docs/toy.md", "## Layers"),
    order="base <- view <- scene",
)

FILES = {
    "toy/__init__.py": '''\
        """Toy package."""
        from .cam import Rig
        ''',
    "toy/util.py": '''\
        """Helpers (toy/util.py); see cam.py and passes/a.py."""
        import logging
        from pathlib import Path

        DATA = Path(__file__).resolve().parent / "data"
        UP = Path(__file__).parents[1]
        LOG = logging.getLogger(__name__)
        SIZE = 3
        ''',
    "toy/cam.py": '''\
        from .util import SIZE


        class Rig:
            size = SIZE
        ''',
    "toy/scene.py": '''\
        def load():
            from . import util  # function-level
            return util.SIZE
        ''',
    "toy/passes/__init__.py": '''\
        from ..cam import Rig  # noqa: F401
        ''',
    "toy/passes/a.py": '''\
        """A pass (see b.py beside it, and ../util.py)."""
        from .. import scene
        from ..util import SIZE
        from . import b


        def run():
            from ..cam import Rig
            return Rig.size + SIZE + scene.load() + b.B
        ''',
    "toy/passes/b.py": '''\
        B = 1
        ''',
    "toy/keep.py": '''\
        """Stays: imports in every form."""
        from . import cam, util
        from .scene import load as load_scene
        from .passes.a import (run,  # the pass
                               SIZE)
        import toy.scene as scene_mod
        import toy.util

        NAME = toy.util.LOG.name  # toy.util's logger
        PATCH = "toy.scene.load"
        WHERE = "toy/cam.py"


        def total():
            return cam.Rig.size + util.SIZE + load_scene() + run() + SIZE + scene_mod.load()
        ''',
    "toy/data/thing.txt": "data\n",
    "toy/shade.glsl": "// mirrors toy/util.py SIZE\n",
    "tests/test_toy.py": '''\
        # checks toy/scene.py
        from toy.util import SIZE
        from toy import cam
        import toy.passes.a as pa


        def test_patch(monkeypatch):
            monkeypatch.setattr("toy.scene.load", lambda: 0)
            assert pa.run() == 2 * SIZE + 1 and cam.Rig.size == SIZE
        ''',
    "tests/layers.py": '''\
        LAYERS = (
            ("toy.util",),
            ("toy.cam", "toy.passes", "toy.scene"),
            ("toy.keep", "toy"),
        )
        ''',
    "docs/toy.md": "`toy/util.py`, `passes/a.py`, `toy/passes/`, `toy.scene.load()`, `data/thing.txt`.\n"
                   "toy/cam.py     the rig\n\n## Layers\n",
}


def git(root, *args):
    return subprocess.run(["git", "-C", str(root), *args], check=True, capture_output=True, text=True).stdout


@pytest.fixture
def repo(tmp_path):
    for rel, text in FILES.items():
        path = tmp_path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))
    git(tmp_path, "init", "-q")
    git(tmp_path, "add", "-A")
    git(tmp_path, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "toy")
    return tmp_path


def run_python(root, code):
    return subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True,
                          env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})


def read(root, rel):
    return (root / rel).read_text()


def test_moves_and_rewrites_every_form(repo, capsys):
    before = run_python(repo, "import toy.keep; print(toy.keep.total(), toy.keep.NAME)")
    assert before.returncode == 0, before.stderr
    assert tool.main(["--root", str(repo)], layout=LAYOUT) == 0
    out = capsys.readouterr().out
    assert "skipped toy.gone: absent" in out

    for old in ("toy/util.py", "toy/cam.py", "toy/scene.py", "toy/passes"):
        assert not (repo / old).exists(), old
    assert read(repo, "toy/base/__init__.py") == '"""Plain helpers."""\n'
    assert (repo / "toy/view/passes/b.py").exists()
    renamed = git(repo, "diff", "--cached", "-M", "--name-status")
    assert "R100\ttoy/passes/b.py\ttoy/view/passes/b.py" in renamed

    keep = read(repo, "toy/keep.py")
    assert "from .view import rig as cam\nfrom .base import util\n" in keep  # a module by name keeps its name
    assert "from .scene.loader import load as load_scene\n" in keep
    assert "from .view.passes.a import (run,  # the pass\n" in keep  # only the module part is rewritten
    assert "import toy.scene.loader as scene_mod\nimport toy.base.util\n" in keep
    assert 'NAME = toy.base.util.LOG.name  # toy.base.util\'s logger' in keep
    assert 'PATCH = "toy.scene.loader.load"' in keep and 'WHERE = "toy/view/rig.py"' in keep

    a = read(repo, "toy/view/passes/a.py")
    assert '"""A pass (see b.py beside it, and ../../base/util.py)."""' in a
    assert "from ...scene import loader as scene\nfrom ...base.util import SIZE\nfrom . import b\n" in a
    assert "    from ..rig import Rig\n" in a  # function level, relative to the new place
    assert read(repo, "toy/view/passes/__init__.py") == "from ..rig import Rig  # noqa: F401\n"
    assert read(repo, "toy/view/rig.py").startswith("from ..base.util import SIZE\n")
    assert "    from ..base import util  # function-level\n" in read(repo, "toy/scene/loader.py")
    assert read(repo, "toy/__init__.py").endswith("from .view.rig import Rig\n")

    util = read(repo, "toy/base/util.py")
    assert '"""Helpers (toy/base/util.py); see view/rig.py and view/passes/a.py."""' in util
    assert 'DATA = Path(__file__).resolve().parents[1] / "data"' in util  # still rayvr's resource folder
    assert "UP = Path(__file__).parents[2]" in util

    test = read(repo, "tests/test_toy.py")
    assert test.startswith("# checks toy/scene/loader.py\nfrom toy.base.util import SIZE\n"
                           "from toy.view import rig as cam\nimport toy.view.passes.a as pa\n")
    assert 'monkeypatch.setattr("toy.scene.loader.load", lambda: 0)' in test
    doc = read(repo, "docs/toy.md")
    assert doc.startswith("`toy/base/util.py`, `view/passes/a.py`, `toy/view/passes/`, `toy.scene.loader.load()`, "
                          "`data/thing.txt`.\ntoy/view/rig.py  the rig\n\n<!-- relayout: packages -->\n## Packages\n")
    assert doc.endswith("\n<!-- /relayout -->\n\n## Layers\n") and max(map(len, doc.splitlines()[3:])) <= 100
    assert " ".join(doc.split("## Packages")[1].split()) == (
        "One package per part of the renderer (`tools/relayout.py` LAYOUT); packages import each other "
        "in one direction: base <- view <- scene. Importing a package runs no other module (its `__init__.py` "
        "imports nothing). - `toy/base/`: Plain helpers. - `toy/view/`: Views and their passes. - `toy/scene/`: "
        "What is shown. - `toy/keep.py`: stays on top - resources found by path, not imported: `toy/data/` "
        "<!-- /relayout --> ## Layers")
    assert read(repo, "toy/shade.glsl") == "// mirrors toy/base/util.py SIZE\n"
    assert read(repo, "tests/layers.py") == textwrap.dedent('''\
        LAYERS = (
            # the packages of tools/relayout.py's layout: their __init__ imports nothing
            ("toy.base", "toy.view", "toy.scene"),
            ("toy.base.util",),
            ("toy.view.rig", "toy.view.passes", "toy.scene.loader"),
            ("toy.keep", "toy"),
        )
        ''')

    after = run_python(repo, "import toy.keep, toy.base.util as u; print(toy.keep.total(), toy.keep.NAME); "
                             "assert (u.DATA / 'thing.txt').is_file() and (u.UP / 'toy').is_dir()")
    assert after.returncode == 0, after.stderr
    assert after.stdout.split()[0] == before.stdout.split()[0]
    assert after.stdout.split()[1] == "toy.base.util"  # the logger's name is the new module's
    pytest_run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"], cwd=repo,
                                capture_output=True, text=True, env={"PYTHONPATH": str(repo), "PATH": "/usr/bin:/bin"})
    assert pytest_run.returncode == 0, pytest_run.stdout


def test_shim_forwards_the_old_path_with_a_warning(repo):
    assert tool.main(["--root", str(repo)], layout=LAYOUT) == 0
    shim = run_python(repo, "import warnings; warnings.simplefilter('error')\n"
                            "import toy.scene.loader  # the package itself says nothing\n"
                            "try:\n    from toy.scene import load\nexcept DeprecationWarning as w:\n    print(w)\n"
                            "warnings.simplefilter('ignore')\nfrom toy.scene import load, loader\n"
                            "print(load is loader.load)")
    assert shim.returncode == 0, shim.stderr
    assert shim.stdout.split("\n")[:2] == ["toy.scene.load moved to toy.scene.loader.load", "True"]


def test_second_run_changes_nothing(repo, capsys):
    assert tool.main(["--root", str(repo)], layout=LAYOUT) == 0
    git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qam", "moved")
    head = git(repo, "rev-parse", "HEAD")
    capsys.readouterr()
    assert tool.main(["--root", str(repo)], layout=LAYOUT) == 0
    assert "nothing to move" in capsys.readouterr().out
    assert git(repo, "status", "--porcelain") == "" and git(repo, "rev-parse", "HEAD") == head


def test_dry_run_changes_nothing(repo, capsys):
    assert tool.main(["--root", str(repo), "--dry-run"], layout=LAYOUT) == 0
    out = capsys.readouterr().out
    assert "toy/scene.py" in out and "-> toy/scene/loader.py" in out and "toy/keep.py" in out
    assert git(repo, "status", "--porcelain") == ""


def test_refuses_an_unplaced_module(repo, capsys):
    (repo / "toy/extra.py").write_text("X = 1\n")
    assert tool.main(["--root", str(repo)], layout=LAYOUT) == 1
    err = capsys.readouterr().err
    assert err.startswith("relayout: error: the layout does not place toy.extra: ") and err.count("\n") == 1
    assert (repo / "toy/util.py").exists()


def test_refuses_a_dirty_tree(repo, capsys):
    (repo / "toy/util.py").write_text("SIZE = 4\n")
    assert tool.main(["--root", str(repo)], layout=LAYOUT) == 1
    assert "uncommitted changes" in capsys.readouterr().err and (repo / "toy/util.py").exists()
