"""Options of the wavefront's persistent threads (rayvr/frame/passes/persistent_threads.py)."""
from __future__ import annotations

from ..options import Option, declare

PERSISTENT_MODES = ("off", "on")

PERSISTENT = declare(Option(
    "persistent", str, "off", "on: the wavefront's trace kernels run as persistent work groups that fetch batches of "
    "rays from an atomic counter (Aila and Laine 2009); off: one invocation per ray (the same images; within 1 % "
    "of each other where measured)", scope="plan", plan_field="persistent", choices=PERSISTENT_MODES,
    label="persistent mode",
    commands=("capture", "preview", "info")))
