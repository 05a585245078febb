"""Options of the tonemap pass (rayvr/frame/passes/tonemap.py)."""
from __future__ import annotations

from ..gl.gpu_layout import TONEMAPPERS
from ..options import Option, declare

MAX_EXPOSURE = 1e6  # x1e6 already turns any lit pixel white

EXPOSURE = declare(Option("exposure", float, 1.0, "linear scale before tonemapping", bounds=(0, MAX_EXPOSURE),
                          lo_open=True, commands=("capture", "preview")))

TONEMAPPER = declare(Option("tonemapper", str, "aces", "the tone curve (glsl/common/color.glsl)", choices=TONEMAPPERS,
                            commands=("capture", "preview")))
