"""Options of the second depth layer (rayvr/frame/passes/second_layer.py)."""
from __future__ import annotations

from ..options import Option, declare

SECOND_LAYER_MODES = ("rays", "peel")

SECOND_LAYER = declare(Option("second_layer", str, "rays", "how the second depth layer (ssr layers = 2) is made: "
                              "primary rays continued through the BVH, or depth peeling in the raster (rayvr bench "
                              "ssrt times both)", scope="plan", plan_field="second_layer", choices=SECOND_LAYER_MODES,
                              label="second layer", commands=("capture", "preview")))
