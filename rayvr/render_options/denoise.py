"""Options of the denoiser (rayvr/frame/passes/denoise.py)."""
from __future__ import annotations

from ..options import Option, declare

MAX_DENOISE_ITERATIONS = 6  # à-trous steps up to 2^5 = 32 pixels: wider, the guides no longer hold
DENOISE = declare(Option("denoise", bool, False, "edge-aware a-trous denoiser on the pixels of the effects the "
                                               "config's `denoise` key lists (default: every traced effect)",
                         scope="plan", plan_field="denoise", commands=("capture", "preview", "info")))
DENOISE_ITERATIONS = declare(Option("denoise_iterations", int, 4, "a-trous iterations (step 2^i; implies --denoise)",
                                    bounds=(1, MAX_DENOISE_ITERATIONS), metavar="K", commands=("capture", "preview"),
                                    implies=(("denoise", True),)))
