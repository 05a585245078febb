"""`path`: progressive path tracing (glsl/effects/path.glsl in the wavefront of rt/wave_shade.comp).
`samples` paths per pixel and frame; at every vertex next-event estimation (`area_samples` light
samples per rect light, shadow rays) and one BSDF sample (Lambert or GGX lobe) combined by
multiple importance sampling (power heuristic), Russian roulette from bounce `rr_start`, at most
`bounces` bounces. Its pixels get no ambient term: the paths are their indirect light. Both eyes
draw the same samples for the same surface point (seeded from it, common/random.glsl)."""
from .base import Effect, Param, register


class Path(Effect):
    name = "path"
    doc = "path traced: NEE + BSDF sampling with MIS, Russian roulette (GGX + Lambert)"
    params = {"samples": Param(int, 1, 1, 1024, "paths per pixel per frame"),
              "bounces": Param(int, 4, 1, 64, "bounces after the pixel's surface (Mitsuba max_depth - 2)"),
              "rr_start": Param(int, 3, 1, 64, "bounce from which Russian roulette may end a path"),
              "area_samples": Param(int, 1, 1, 1024, "light samples per rect light at each vertex (x samples at "
                                                     "the pixel's surface: one set per path)")}
    traced = True
    path_vertices = True  # follows its paths for `bounces` hit events (not `reflective`: a mirror ray ends on it)
    shader = "effects/path.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    # The pixel's surface takes area_samples light samples per path (as Mitsuba's path tracer does
    # per camera sample), not per pixel: at equal samples its direct light is as converged.
    shader_defines = {"LIGHT_MIS": 1, "PIXEL_LIGHT_SAMPLES_PER_PATH": 1}
    sweep = {"samples": ((1, 2, 4, 8, 16), (1, 4)), "bounces": ((1, 2, 4, 8), (1, 4)),
             "area_samples": ((1, 2, 4), (1,))}
    reference = {"mirror": 40, "glossy": 40, "diffuse": 40}  # the most accurate rung for every class

    def reference_params(self, quality: dict) -> dict:
        """Many paths (`path_samples`), `bounces`, one light sample per vertex (paths average them)."""
        q = {"samples": quality.get("path_samples", quality.get("samples", 1)),
             "bounces": quality.get("bounces", 4), "area_samples": 1}
        return {k: p.clamp(q[k]) for k, p in self.params.items() if k in q}

    def passes(self):
        from ..passes.trace_effect import TraceEffectPass
        return [TraceEffectPass(self)]


register(Path())
