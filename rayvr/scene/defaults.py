"""What a command renders when it is not told: the built-in room with its own effect config, and
the configs rayvr ships, named by file name alone.

The room (rayvr/assets/default_room.glb) is the first image a user sees, so it shows the ladder:
ray-traced shadows, mirrors and glossy gold and floor (rayvr/assets/default_room.toml). A scene of
the user's own has no config of rayvr's: without --materials it renders all `raster`
(materials.load_config(None)), as does the room with `--materials raster.toml`.
"""
from __future__ import annotations

from pathlib import Path

from .loader import ASSETS_DIR

ROOM_CONFIG = ASSETS_DIR / "default_room.toml"
ROOM_NOTICE = ("rayvr: the built-in room renders with its own effects (default_room.toml: ray-traced shadows, "
               "mirrors, glossy gold and floor); --materials raster.toml renders it plain raster")


def shipped(name: str) -> Path | None:
    """The config rayvr ships under this bare file name (raster.toml, path_room.toml, ...), or None."""
    if Path(name).name != name or not name.endswith(".toml"):
        return None
    path = ASSETS_DIR / name
    return path if path.is_file() else None


def materials_for(scene, materials) -> tuple:
    """(the material config a command renders with, what to tell the user or None): `materials` as
    given (a bare name of a shipped config when no such file is here), or for the built-in room
    (`scene` None) its own config, with a line that says so."""
    if materials is not None:
        return (materials if Path(materials).exists() else (shipped(str(materials)) or materials)), None
    if scene is None:
        return str(ROOM_CONFIG), ROOM_NOTICE
    return None, None
