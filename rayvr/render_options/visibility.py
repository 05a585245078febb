"""Options of the visibility raster (rayvr/frame/passes/visibility.py)."""
from __future__ import annotations

from ..options import Option, declare

LAYER_MODES = ("vertex", "geometry", "multiview", "passes")


LAYER_MODE = declare(Option("layer_mode", str, "auto", "how the stereo G-buffer reaches both layers (auto: vertex "
                                                           "where the GL sets gl_Layer in the vertex stage, else "
                                                           "geometry)",
                            scope="plan", choices=("auto",) + LAYER_MODES, label="layer mode", plan_field="layer_mode",
                            commands=("capture", "preview")))
