"""Options of the stereo modes (rayvr/frame/stereo.py)."""
from __future__ import annotations

from ..options import Option, declare

STEREO_MODES = ("dual", "warp", "reuse")


STEREO = declare(Option("stereo", str, "dual", "how the second eye is made: dual renders both; warp synthesizes "
                        "both from a central view through its screen-space quadtree; reuse gives the right eye the "
                        "left eye's shading where it sees the same surface", scope="plan", choices=STEREO_MODES,
                        label="stereo mode", plan_field="stereo", commands=("capture", "preview", "info")))

WARP_LAYERS = declare(Option("warp_layers", int, 2, "depth layers of the central view warp traces: 2 finds what lies "
                             "behind its first surfaces (the second layer, --second-layer), 1 inpaints those "
                             "disocclusions", scope="plan", plan_field="depth_layers", choices=(1, 2),
                             label="warp layer count", commands=("capture", "preview")))
