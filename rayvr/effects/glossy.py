"""`glossy`: `samples` GGX reflection rays per pixel by VNDF importance sampling, each followed
like a mirror ray (glsl/rt/wave_shade.comp, EFFECT_GLOSSY). Rect lights are found by light samples
and by GGX rays: multiple importance sampling (power heuristic) counts their highlight once."""
from .base import Effect, Param, register
from .shadows import AREA_SAMPLES, AREA_SAMPLES_SWEEP


class Glossy(Effect):
    name = "glossy"
    id = 4
    doc = "+ GGX glossy reflections (VNDF importance sampling)"
    params = {"samples": Param(int, 4, 1, 1024, "reflection rays per pixel"),
              "bounces": Param(int, 1, 1, 8, "reflection bounces"),
              "area_samples": AREA_SAMPLES}
    traced = True
    reflective = True
    shader = "effects/glossy.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    shader_defines = {"LIGHT_MIS": 1}
    sweep = {"samples": ((1, 2, 4, 8, 16, 32), (1, 4)), "bounces": ((1, 2, 3, 4, 8), (1, 2)),
             "area_samples": AREA_SAMPLES_SWEEP}
    reference = {"glossy": 30, "mirror": 20}

    def passes(self):
        from ..passes.trace_effect import TraceEffectPass
        return [TraceEffectPass(self)]


register(Glossy())
