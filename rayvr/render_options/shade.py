"""Options of the shading of every material: its ambient light and the background (rayvr/frame/passes/shade.py)."""
from __future__ import annotations

from ..gl.limits import FLOAT32_MAX
from ..options import Option, declare

def _rgb(name: str):
    """An option's check of linear RGB: 3 numbers, or the text "R,G,B" (a flag)."""
    def convert(value) -> tuple:
        if isinstance(value, str):
            try:
                value = tuple(float(v) for v in value.split(","))
            except ValueError:
                pass  # named below as what it is not
        if isinstance(value, str) or not hasattr(value, "__len__") or len(value) != 3 or \
                not all(isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) <= FLOAT32_MAX
                        for v in value):
            raise ValueError(f"{name} must be 3 finite numbers R,G,B (linear), got {value!r}")
        return tuple(float(v) for v in value)
    return convert


AMBIENT = declare(Option("ambient", tuple, (0.03, 0.03, 0.03), "ambient light every material adds (linear RGB; "
                         "raise it to see an interior away from its lights)",
                         scope="material", metavar="R,G,B", convert=_rgb("ambient"), commands=("capture", "preview")))

BACKGROUND = declare(Option("background", tuple, (0.02, 0.02, 0.025), "radiance where no surface is (linear RGB)",
                            scope="material", metavar="R,G,B", convert=_rgb("background"),
                            commands=("capture", "preview")))
