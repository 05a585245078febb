"""`glossy`: `samples` GGX reflection rays per pixel by VNDF importance sampling, each followed
like a mirror ray (glsl/rt/wave_shade.comp, EFFECT_GLOSSY). Rect lights are found by light samples
and by GGX rays: multiple importance sampling (power heuristic) counts their highlight once."""
from ..effect_registry import Effect, Param, register
from ..passes.trace_effect import WAVE_AREA_SAMPLES, WAVE_HIT_AREA_SAMPLES, WAVE_BOUNCES, WAVE_SAMPLES, TraceEffectPass
from .shadows import AREA_SAMPLES, AREA_SAMPLES_SWEEP, HIT_AREA_SAMPLES, HIT_AREA_SAMPLES_SWEEP


class Glossy(Effect):
    name = "glossy"
    doc = "+ GGX glossy reflections (VNDF importance sampling)"
    params = {WAVE_SAMPLES: Param(int, 4, 1, 1024, "reflection rays per pixel"),
              WAVE_BOUNCES: Param(int, 1, 1, 8, "reflection bounces"),
              WAVE_AREA_SAMPLES: AREA_SAMPLES,
              WAVE_HIT_AREA_SAMPLES: HIT_AREA_SAMPLES}
    traced = True
    reflective = True
    shader = "effects/glossy.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    shader_defines = {"LIGHT_MIS": 1}
    sweep = {WAVE_SAMPLES: ((1, 2, 4, 8, 16, 32), (1, 4)), WAVE_BOUNCES: ((1, 2, 3, 4, 8), (1, 2)),
             WAVE_AREA_SAMPLES: AREA_SAMPLES_SWEEP,
             WAVE_HIT_AREA_SAMPLES: HIT_AREA_SAMPLES_SWEEP}
    reference = {"glossy": 30, "mirror": 20}

    def passes(self):
        return [TraceEffectPass(self)]


register(Glossy())
