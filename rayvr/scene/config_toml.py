"""A material config written out as TOML (the format rayvr/scene/materials.py reads): what a
budget pick hands the user to save and reuse. Every material by its index with its effect and
all of its parameters spelled out, so the file means the same to a later rayvr whose defaults
moved; the frame-wide render options as the [render] table.
"""
from __future__ import annotations

import json
import math

from .. import options
from .materials import Assignment


def toml_value(value) -> str:
    """One TOML value: a string, bool, int, finite float or a list/tuple of them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"TOML has no value for {value!r} in a rayvr config")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} {value!r} into a config")


def config_toml(names: list[str], assignments: list[Assignment], render: dict | None = None,
                denoise: tuple | None = None, comments: tuple[str, ...] = ()) -> str:
    """The config giving material i of `names` assignments[i] (effect, parameters, importance),
    with `render` as its [render] table and `denoise` as its denoised effects; `comments` on top."""
    lines = [f"# {c}" for c in comments] + ['default = "raster"']
    if denoise is not None:
        lines.append(f"denoise = {toml_value(list(denoise))}")
    if render:
        lines += ["", f"[{options.TABLE}]"] + [f"{k} = {toml_value(v)}" for k, v in render.items()]
    lines += ["", "[ids]"]
    for index, (name, a) in enumerate(zip(names, assignments)):
        fields = {"effect": a.effect, **a.params}
        if a.importance != 1.0:
            fields["importance"] = a.importance
        body = ", ".join(f"{k} = {toml_value(v)}" for k, v in fields.items())
        lines.append(f"{index} = {{ {body} }}  # {json.dumps(name)}")
    return "\n".join(lines) + "\n"
