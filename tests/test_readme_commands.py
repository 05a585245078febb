"""Every command README.md shows runs: the `rayvr ...` lines of its bash blocks and its Python
snippet, read out of the README itself (a command edited there is tested as edited). A user's
placeholders get real files (scene.glb: the built-in room's own GLB, materials.toml: a config,
camera_path.json: a two-pose path), and the sizes, frame, view and sample counts shrink so that
the whole README runs in seconds on llvmpipe; nothing else of a command changes. Preview lines
open a window: they run under the test session's display for a moment (skipped without one)."""
from __future__ import annotations

import json
import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from test_preview import display  # noqa: F401  (the session's Xvfb: a fixture here too)

README = Path(__file__).resolve().parents[1] / "README.md"
ROOM_GLB = Path(__file__).resolve().parents[1] / "rayvr" / "assets" / "default_room.glb"
SMALL = {"--size": "32x24", "--frames": "2", "--spp": "2", "--views": "sphere:2"}


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(), re.S)


def readme_commands() -> list[str]:
    """The `rayvr ...` and `python app.py ...` lines of README's bash blocks, comments cut."""
    out = []
    for block in blocks("bash"):
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            if line.startswith(("rayvr ", "python app.py")):
                out.append(line)
    return out


COMMANDS = readme_commands()


def test_readme_shows_commands():
    assert len(COMMANDS) >= 12 and any(c.startswith("rayvr preview") for c in COMMANDS)


def shrink(words: list[str], files: dict) -> list[str]:
    """The command's words with placeholders made real and counts made small."""
    out, i = [], 0
    while i < len(words):
        w = words[i]
        if w in SMALL and i + 1 < len(words):
            out += [w, SMALL[w]]
            i += 2
            continue
        out.append(str(files.get(w, w)))
        i += 1
    if out[0] in ("capture", "preview") and "--size" not in out:
        out += ["--size", SMALL["--size"]]
    return out


@pytest.fixture
def files(tmp_path):
    cfg = tmp_path / "materials.toml"
    cfg.write_text('default = "shadows"\n[materials]\n"mirror*" = { effect = "reflections", bounces = 1 }\n')
    path = tmp_path / "camera_path.json"
    path.write_text(json.dumps({"poses": [{"position": [0.0, 1.6, 3.0], "target": [0.0, 1.0, 0.0]},
                                          {"position": [0.5, 1.6, 3.0], "target": [0.0, 1.0, 0.0]}]}))
    return {"scene.glb": ROOM_GLB, "materials.toml": cfg, "camera_path.json": path}


@pytest.mark.parametrize("command", COMMANDS)
def test_readme_command_runs(command, files, tmp_path, monkeypatch, request):
    words = shlex.split(command)
    if "exr" in words and importlib.util.find_spec("OpenEXR") is None:
        pytest.skip("--format exr needs the optional OpenEXR (pip install 'rayvr[exr]')")
    monkeypatch.chdir(tmp_path)   # outputs (out/, shots/, orbit/, views/) land in the test's folder
    if words[0] == "python":      # python app.py ...: the repository's preview script
        args = [sys.executable, str(README.parent / "app.py"), *shrink(["preview", *words[2:]], files)[1:]]
    else:
        args = [sys.executable, "-m", "rayvr", *shrink(words[1:], files)]
    if "preview" in args or "app.py" in args[1]:
        request.getfixturevalue("display")   # skips without a display
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            out, err = proc.communicate(timeout=6)
        except subprocess.TimeoutExpired:   # the window is up and rendering: what a user sees
            proc.terminate()
            out, err = proc.communicate(timeout=30)
            assert "error" not in err.lower(), f"{command}: {err[-2000:]}"
            return
        assert proc.returncode == 0, f"{command}: {err[-2000:]}"
        return
    run = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"{command} -> {' '.join(map(str, args[2:]))}: {run.stderr[-2000:]}"


def test_readme_python_snippet_runs(files, tmp_path, monkeypatch):
    (snippet,) = [b for b in blocks("python") if "Renderer(" in b]
    code = snippet.replace('"scene.glb"', repr(str(files["scene.glb"]))).replace(
        '"materials.toml"', repr(str(files["materials.toml"]))).replace("size=(1440, 1600)", "size=(32, 24)")
    assert code != snippet
    monkeypatch.chdir(tmp_path)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "gbuffer" in run.stdout   # it prints the frame's timings
