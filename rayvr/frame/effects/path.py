"""`path`: progressive path tracing (glsl/effects/path.glsl in the wavefront of rt/wave_shade.comp).
`samples` paths per pixel and frame; at every vertex next-event estimation (`area_samples` light
samples per rect light, shadow rays) and one BSDF sample (Lambert or GGX lobe) combined by
multiple importance sampling (power heuristic), Russian roulette from bounce `rr_start`, at most
`bounces` bounces. Its pixels get no ambient term: the paths are their indirect light. Both eyes
draw the same samples for the same surface point (seeded from it, common/random.glsl)."""
from ..effect_registry import Effect, Param, register
from ..passes.trace_effect import WAVE_AREA_SAMPLES, WAVE_BOUNCES, WAVE_SAMPLES, TraceEffectPass


class Path(Effect):
    name = "path"
    doc = "path traced: NEE + BSDF sampling with MIS, Russian roulette (GGX + Lambert)"
    params = {WAVE_SAMPLES: Param(int, 1, 1, 1024, "paths per pixel per frame"),
              WAVE_BOUNCES: Param(int, 4, 1, 64, "bounces after the pixel's surface (Mitsuba max_depth - 2)"),
              "rr_start": Param(int, 3, 1, 64, "bounce from which Russian roulette may end a path"),
              WAVE_AREA_SAMPLES: Param(int, 1, 1, 1024, "light samples per rect light at each vertex (x samples "
                                                         "at the pixel's surface: one set per path)")}
    traced = True
    path_vertices = True  # follows its paths for `bounces` hit events (not `reflective`: a mirror ray ends on it)
    shader = "effects/path.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    # The pixel's surface takes area_samples light samples per path (as Mitsuba's path tracer does
    # per camera sample), not per pixel: at equal samples its direct light is as converged.
    shader_defines = {"LIGHT_MIS": 1, "PIXEL_LIGHT_SAMPLES_PER_PATH": 1}
    sweep = {WAVE_SAMPLES: ((1, 2, 4, 8, 16), (1, 4)), WAVE_BOUNCES: ((1, 2, 4, 8), (1, 4)),
             WAVE_AREA_SAMPLES: ((1, 2, 4), (1,))}
    reference = {"mirror": 40, "glossy": 40, "diffuse": 40}  # the most accurate rung for every class

    def reference_params(self, quality: dict) -> dict:
        """Many paths (`path_samples`), `bounces`, one light sample per vertex (paths average them)."""
        q = {WAVE_SAMPLES: quality.get("path_samples", quality.get("samples", 1)),
             WAVE_BOUNCES: quality.get("bounces", 4), WAVE_AREA_SAMPLES: 1}
        return {k: p.clamp(q[k]) for k, p in self.params.items() if k in q}

    def passes(self):
        return [TraceEffectPass(self)]


register(Path())
