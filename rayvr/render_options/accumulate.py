"""Options of the accumulate pass (rayvr/frame/passes/accumulate.py)."""
from __future__ import annotations

from ..options import Option, declare

ACCUMULATE = declare(Option("accumulate", bool, False, "successive frames add samples while nothing changes; "
                                                 "any change starts over", scope="plan", plan_field="accumulate"))
TEMPORAL = declare(Option("temporal", bool, False, "camera paths: carry each frame's samples into the next by "
                                             "reprojection (pinhole)", commands=("capture", "preview"),
                          implies=(("accumulate", True),)))
