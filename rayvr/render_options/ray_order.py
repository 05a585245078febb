"""Options of the wavefront's ray order (rayvr/frame/passes/ray_order.py)."""
from __future__ import annotations

from ..options import Option, declare

RAY_ORDERS = ("none", "morton")

RAY_ORDER = declare(Option(
    "ray_order", str, "none", "the order the wavefront traces its rays in: none (as shaded) or morton (sorted by "
    "direction octant and origin cell before each trace kernel; the same images, slower where measured: its "
    "sort costs more than it saves)",
    scope="plan", plan_field="ray_order", choices=RAY_ORDERS, label="ray order",
    commands=("capture", "preview", "info")))
