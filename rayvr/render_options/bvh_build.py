"""Options of the BVH build (rayvr/accel/bvh.py)."""
from __future__ import annotations

from ..options import Option, declare

BUILDS = ("sah", "sbvh")    # build_bvh without / with spatial splits (RenderSettings.bvh_build)
BVH_BUILD = declare(Option("bvh_build", str, "sah", "BVH build: sah (binned SAH) or sbvh (spatial splits: "
                           "lower SAH cost, up to 30 % more triangle references, a longer build; "
                           "accel/sbvh.py)", scope="plan", plan_field="bvh_build", choices=BUILDS,
                           label="BVH build", commands=("capture", "preview")))
