"""The scenes and views every benchmark uses, so figures from different benchmarks compare."""
from __future__ import annotations

import os
from pathlib import Path

from ..scene import loader as scene_mod
from ..frame.cameras.rig import Pose, StereoRig

# The workspace's third-party scenes (not shipped); RAYVR_SCENES points elsewhere.
SHARED_SCENES = Path(os.environ.get("RAYVR_SCENES") or Path(__file__).resolve().parents[2].parent / "shared" / "scenes")

# name -> (file relative to SHARED_SCENES or None for the built-in room, head pose or None for
# the file's own camera)
SCENES = {
    "default": (None, None),
    "sponza": ("sponza_dabrovic/sponza.obj", Pose.look_at((-10.0, 3.0, -0.5), (8.0, 5.0, 0.5))),
}


def shipped_config(scene_name: str):
    """The material config shipped for a benchmark scene (rayvr/assets/<scene>.toml), if any."""
    path = scene_mod.ASSETS_DIR / ("default_room.toml" if scene_name == "default" else f"{scene_name}.toml")
    return path if path.exists() else None


def load_bench_scene(name: str):
    """(Scene, pose) or (None, why it is missing)."""
    if name not in SCENES:
        raise ValueError(f"unknown benchmark scene {name!r}; choose from {', '.join(SCENES)}")
    rel, pose = SCENES[name]
    if rel is None:
        return scene_mod.load(None), pose
    path = SHARED_SCENES / rel
    if not path.exists():
        return None, f"{path} not found (the shared scenes folder is absent)"
    return scene_mod.load(path), pose


def bench_scenes(names, size, skipped: dict):
    """Yield (name, scene, rig) for each available scene; missing ones go into `skipped`."""
    for name in names:
        scene, pose = load_bench_scene(name)
        if scene is None:
            skipped[name] = pose
            continue
        rig = StereoRig.for_scene(scene, size=size)
        if pose is not None:
            rig.pose = pose
        yield name, scene, rig
