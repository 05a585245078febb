"""`reflections`: a mirror ray through up to `bounces` reflective surfaces, each hit lit with its
own direct light and shadows (glsl/rt/wave_shade.comp, EFFECT_REFLECTIONS)."""
from .base import Effect, Param, register
from .shadows import AREA_SAMPLES, AREA_SAMPLES_SWEEP


class Reflections(Effect):
    name = "reflections"
    id = 3
    doc = "+ ray-traced mirror reflections"
    params = {"bounces": Param(int, 1, 1, 16, "reflection bounces"), "area_samples": AREA_SAMPLES}
    traced = True
    denoised = False  # mirror reflections are sharp detail, not noise: --denoise leaves them
    reflective = True  # a reflection ray that meets it goes on in its mirror direction
    shader = "effects/reflections.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    sweep = {"bounces": ((1, 2, 3, 4, 8), (1, 2)), "area_samples": AREA_SAMPLES_SWEEP}
    reference = {"mirror": 30}

    def passes(self):
        from ..passes.trace_effect import TraceEffectPass
        return [TraceEffectPass(self)]


register(Reflections())
