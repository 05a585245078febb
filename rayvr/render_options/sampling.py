"""Options of a sample's sub-rays (rayvr/frame/cameras/sampling.py)."""
from __future__ import annotations

from ..options import Option, declare

SAMPLE_COUNTS = (1, 4, 8, 16, 32)  # sub-rays per sample rayvr offers (--msaa); 32 fits a coverage mask

MSAA = declare(Option("msaa", int, 1, "sub-rays per sample (anti-aliasing; casts primary rays): shading once per "
                      "pixel per distinct triangle, or per sub-ray with --ssaa", scope="plan", choices=SAMPLE_COUNTS,
                      label="sub-ray count", plan_field="subsamples", commands=("capture", "preview", "info", "bench")))

SSAA = declare(Option("ssaa", bool, False, "shade every sub-ray of --msaa N (supersampling)", scope="plan",
                      plan_field="shading", commands=("capture", "preview", "info", "bench")))
