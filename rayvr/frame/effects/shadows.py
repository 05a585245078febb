"""`shadows`: direct light with ray-traced shadows; rect lights soft by `area_samples` random
points per pixel (glsl/rt/wave_shade.comp, EFFECT_SHADOWS)."""
from ..effect_registry import Effect, Param, register
from ..passes.trace_effect import WAVE_AREA_SAMPLES, TraceEffectPass

AREA_SAMPLES = Param(int, 4, 1, 1024, "shadow rays per area light per pixel")
AREA_SAMPLES_SWEEP = ((1, 2, 4, 8, 16, 32), (1, 4, 16))
# Where a reflection ray lands (reflections, glossy, ssr), its surface needs no more light samples
# than the pixel takes at its own: with the default 0 the pixel's `area_samples` are spread over its
# rays (area_samples / rays, at least one a ray: a glossy floor's 4 rays cast 4 shadow rays at their
# hits, not 4 x area_samples; a mirror ray keeps area_samples, its hit seen as sharply as a surface).
HIT_AREA_SAMPLES = Param(int, 0, 0, 1024, "shadow rays per area light where a reflection ray lands "
                                          "(0: area_samples spread over the pixel's rays, at least 1 a ray)")
HIT_AREA_SAMPLES_SWEEP = ((0, 1, 4, 16), (0, 4))


class Shadows(Effect):
    name = "shadows"
    doc = "+ ray-traced hard shadows; area lights soft with N samples"
    params = {WAVE_AREA_SAMPLES: AREA_SAMPLES}
    traced = True
    shader = "effects/shadows.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    sweep = {WAVE_AREA_SAMPLES: AREA_SAMPLES_SWEEP}
    reference = {"mirror": 10, "glossy": 10, "diffuse": 10}

    def passes(self):
        return [TraceEffectPass(self)]


register(Shadows())
