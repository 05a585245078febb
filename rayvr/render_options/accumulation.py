"""Options of sample accumulation and its random sequence (rayvr/frame/accumulation.py)."""
from __future__ import annotations

from ..options import Option, declare

SEED = declare(Option("seed", int, 0, "random sequence of the sampled effects: the same seed gives the same image",
                      bounds=(0, 2**32 - 1), commands=("capture", "preview")))  # the shaders' frame_seed is a uint
