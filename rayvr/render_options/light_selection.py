"""Options of the traced effects' light sampling (rayvr/scene/light_selection.py)."""
from __future__ import annotations

from ..options import Option, declare

LIGHT_PICKS = declare(Option("light_picks", int, 0, "traced effects light each surface with K lights drawn by power "
                             "(their shadow rays only; unbiased, noisier) instead of every light; 0: every light",
                             bounds=(0, 64), scope="plan", plan_field="light_picks", metavar="K",
                             commands=("capture", "preview", "info", "bench")))


# Adaptive area-light shadows (glsl/rt/wave_trace.comp adaptive_run): of a rect light's N shadow rays
# at a surface, K (or N / 4, whichever is more) spread over its lattice are traced first and the rest
# only where those disagree (a penumbra). Wholly lit or wholly hidden lights cost K rays instead of N; the bias lies in
# penumbrae narrower than the probes' spacing (tests/test_adaptive_shadows.py bounds it).
SHADOW_PROBES = declare(Option("shadow_probes", int, 4, "area-light shadows: trace K of a light's shadow rays (or a "
                               "quarter of them, if more) first and the rest only where those disagree (a "
                               "penumbra); 0: trace every ray",
                               bounds=(0, 1024), metavar="K", commands=("capture", "preview", "info", "bench")))
