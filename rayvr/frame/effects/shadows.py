"""`shadows`: direct light with ray-traced shadows; rect lights soft by `area_samples` random
points per pixel (glsl/rt/wave_shade.comp, EFFECT_SHADOWS)."""
from ..effect_registry import Effect, Param, register
from ..passes.trace_effect import WAVE_AREA_SAMPLES, TraceEffectPass

AREA_SAMPLES = Param(int, 4, 1, 1024, "shadow rays per area light per pixel")
AREA_SAMPLES_SWEEP = ((1, 2, 4, 8, 16, 32), (1, 4, 16))


class Shadows(Effect):
    name = "shadows"
    id = 1
    doc = "+ ray-traced hard shadows; area lights soft with N samples"
    params = {WAVE_AREA_SAMPLES: AREA_SAMPLES}
    traced = True
    shader = "effects/shadows.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    sweep = {WAVE_AREA_SAMPLES: AREA_SAMPLES_SWEEP}
    reference = {"mirror": 10, "glossy": 10, "diffuse": 10}

    def passes(self):
        return [TraceEffectPass(self)]


register(Shadows())
