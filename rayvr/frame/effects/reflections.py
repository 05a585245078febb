"""`reflections`: a mirror ray through up to `bounces` reflective surfaces, each hit lit with its
own direct light and shadows (glsl/rt/wave_shade.comp, EFFECT_REFLECTIONS)."""
from ..effect_registry import Effect, Param, register
from ..passes.trace_effect import WAVE_AREA_SAMPLES, WAVE_HIT_AREA_SAMPLES, WAVE_BOUNCES, TraceEffectPass
from .shadows import AREA_SAMPLES, AREA_SAMPLES_SWEEP, HIT_AREA_SAMPLES, HIT_AREA_SAMPLES_SWEEP


class Reflections(Effect):
    name = "reflections"
    doc = "+ ray-traced mirror reflections"
    params = {WAVE_BOUNCES: Param(int, 1, 1, 16, "reflection bounces"), WAVE_AREA_SAMPLES: AREA_SAMPLES,
              WAVE_HIT_AREA_SAMPLES: HIT_AREA_SAMPLES}
    traced = True
    denoised = False  # mirror reflections are sharp detail, not noise: --denoise leaves them
    reflective = True  # a reflection ray that meets it goes on in its mirror direction
    shader = "effects/reflections.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    sweep = {WAVE_BOUNCES: ((1, 2, 3, 4, 8), (1, 2)), WAVE_AREA_SAMPLES: AREA_SAMPLES_SWEEP,
             WAVE_HIT_AREA_SAMPLES: HIT_AREA_SAMPLES_SWEEP}
    reference = {"mirror": 30}

    def passes(self):
        return [TraceEffectPass(self)]


register(Reflections())
