"""Options of the screen-space quadtree (rayvr/frame/passes/quadtree.py)."""
from __future__ import annotations

from ..options import Option, declare

QUADTREE_ADAPT = declare(Option(
    "quadtree_adapt", float, 0.0, "distance-adaptive quadtree thresholds (Widmer et al. §6): gamma_dist and the "
    "normal angle grow by 1 + this x the node's view depth (scene units); 0 = off", bounds=(0, 1e6),
    commands=("capture", "preview")))
