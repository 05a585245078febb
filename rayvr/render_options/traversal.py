"""Options of the BVH layouts the traced rays walk (rayvr/accel/gpu.py)."""
from __future__ import annotations

from ..gl.gpu_layout import BVH_LAYOUTS
from ..options import Option, declare

RAY_KINDS = ("primary", "shadow", "reflect")   # RenderSettings.traversal: a layout for each

# The renderer's layout per ray kind: the fastest on the GPU (docs/design.md). bvh4 for primary rays
# (1.00x, 1.06x of bvh2: bench rays, room and Sponza), bvh2 for shadow
# rays (bvh4 0.78x, 0.92x there; cwbvh made the room's area-light shadows 20-40 % slower and Sponza's
# 10-13 % faster), cwbvh for reflection rays, the closest hits of reflections, glossy, path and
# photons (3 head poses: path 1 spp 4 bounces 11.4 -> 10.3 ms in the room, 38.5 ->
# 35.2 on Sponza, no frame slower).
DEFAULT_TRAVERSAL = ("bvh4", "bvh2", "cwbvh")


def parse_traversal(text: str) -> tuple[str, str, str]:
    """'bvh8' (every ray kind) or 'primary=bvh8,shadow=bvh4' (others as DEFAULT_TRAVERSAL) -> a layout
    per RAY_KINDS."""
    out = dict(zip(RAY_KINDS, DEFAULT_TRAVERSAL))
    for part in (x.strip() for x in text.split(",") if x.strip()):
        kind, _, layout = part.rpartition("=")
        if kind and kind not in RAY_KINDS:
            raise ValueError(f"unknown ray kind {kind!r} in {text!r}; allowed: {', '.join(RAY_KINDS)}")
        check_layout(layout)
        for k in ((kind,) if kind else RAY_KINDS):
            out[k] = layout
    return tuple(out.values())


def check_layout(layout: str) -> int:
    """The node width of a layout name (2, 4, 8); a clear error for an unknown one."""
    if layout not in BVH_LAYOUTS:
        raise ValueError(f"BVH layout must be one of {', '.join(BVH_LAYOUTS)}, got {layout!r}")
    return BVH_LAYOUTS[layout]


def traversal_value(value) -> tuple[str, str, str]:
    """A layout per RAY_KINDS from 'bvh8', 'primary=bvh8,...' (parse_traversal) or a sequence of layouts."""
    if isinstance(value, str):
        return parse_traversal(value)
    value = tuple(value) if isinstance(value, (tuple, list)) else value
    if not isinstance(value, tuple) or len(value) != len(RAY_KINDS):
        raise ValueError(f"traversal needs a layout for each of {', '.join(RAY_KINDS)}, got {value!r}")
    for layout in value:
        check_layout(layout)
    return value


TRAVERSAL = declare(Option(
    "traversal", tuple, DEFAULT_TRAVERSAL, "BVH node layout of the traced rays: one for all (bvh2, bvh4, bvh8, cwbvh) or per "
    "ray kind, e.g. primary=bvh8,shadow=bvh4,reflect=bvh2; kinds not named keep the default (the fastest "
    "measured; bvh2 is the reference)", scope="plan", plan_field="traversal", metavar="LAYOUTS", convert=traversal_value,
    commands=("capture", "preview", "bench")))
