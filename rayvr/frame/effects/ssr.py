"""`ssr`: reflections traced in screen space through the depth quadtree (Widmer et al. 2015,
rayvr/frame/passes/quadtree.py) instead of the BVH: a mirror ray on surfaces with roughness up to
`mirror_roughness`, and, with `samples` > 0, that many GGX rays (VNDF importance sampling, as
`glossy`) on rougher ones (else mirror rays there too). The quadtree's merge thresholds
(`gamma_norm`, `gamma_dist`) are frame parameters: one tree serves every ssr material, built with
the strictest any of them asks for. A
surface is a slab of relative `thickness` behind each depth layer's planes. With `layers` = 1 a ray
that goes deeper than the slab passed behind an object, and what it meets there is hidden from
the screen; with `layers` = 2 the second depth layer (frame/passes/second_layer.py) answers for the
space behind the first (occlusion volumes, §4.1) and only rays behind both are unanswered.
Unanswered rays, rays that leave the image, head for the camera or cross it without a hit fall
back to the BVH when `fallback` is 1; with `fallback` 0 misses see the background and a ray that
passed behind an object takes the pixel just before it (the near side of the depth
discontinuity: inpainting). The pixel event is the `reflections` / `glossy` one; a hit found on
screen is shaded like a BVH hit (its own direct light and shadows)."""
import math

from ..effect_registry import Effect, Param, register
from ..passes.quadtree import GAMMA_DIST, GAMMA_NORM
from ..passes.second_layer import DEPTH_LAYERS
from ..passes.trace_effect import WAVE_AREA_SAMPLES, WAVE_HIT_AREA_SAMPLES, WAVE_BOUNCES, WAVE_SAMPLES, TraceEffectPass
from .shadows import AREA_SAMPLES, AREA_SAMPLES_SWEEP, HIT_AREA_SAMPLES, HIT_AREA_SAMPLES_SWEEP

# the roughness up to which a surface is a mirror: ssr's default for one mirror path, and the
# reference image's mirror class (rayvr/quality/reference_images.py)
MIRROR_ROUGHNESS = 0.05
COS = {deg: math.cos(math.radians(deg)) for deg in (3, 10, 25)}


class ScreenSpaceReflections(Effect):
    name = "ssr"
    doc = "+ screen-space mirror and GGX reflections through the depth quadtree, BVH fallback"
    params = {
        # one quadtree per frame: the strictest thresholds of the materials (frame/passes/quadtree.py)
        GAMMA_NORM: Param(float, COS[10], 0.0, 1.0, "quadtree plane merge: cosine of the largest normal angle "
                                                      "(1 = lossless)", scope="frame", reduce="max"),
        GAMMA_DIST: Param(float, 1e-3, 0.0, 1.0, "quadtree plane merge: largest relative depth error (0 = lossless)",
                          scope="frame", reduce="min"),
        DEPTH_LAYERS: Param(int, 1, 1, 2, "depth layers traced: 1 (behind an object is unknown) or 2 (the "
                                          "second layer answers there)"),
        "fallback": Param(int, 1, 0, 1, "1: trace in the BVH what the screen cannot answer; 0: misses see the "
                                        "background, occluded rays inpaint"),
        "thickness": Param(float, 0.02, 0.0, 1e30, "a surface is a slab this deep behind each layer (relative "
                                                    "depth); a ray deeper than that passed behind it"),
        WAVE_BOUNCES: Param(int, 1, 1, 4, "reflection bounces (each traced in screen space first)"),
        WAVE_SAMPLES: Param(int, 0, 0, 1024, "GGX rays per pixel on surfaces rougher than mirror_roughness "
                                             "(0: a mirror ray everywhere)"),
        "mirror_roughness": Param(float, MIRROR_ROUGHNESS, 0.0, 1.0, "surfaces up to this roughness take one "
                                                                     "mirror ray whatever `samples` says"),
        WAVE_AREA_SAMPLES: AREA_SAMPLES,
        WAVE_HIT_AREA_SAMPLES: HIT_AREA_SAMPLES,
    }
    traced = True
    denoised = False  # mirror reflections are sharp detail, not noise: --denoise leaves them
    reflective = True
    uses_quadtree = True
    shader = "effects/ssr.glsl"  # the reflections / glossy pixel events by roughness
    sweep = {GAMMA_NORM: ((1.0, COS[3], COS[10], COS[25]), (1.0, COS[10])),
             "thickness": ((0.005, 0.02, 0.1, 1e30), (0.02, 1e30)),
             GAMMA_DIST: ((0.0, 1e-5, 1e-3, 1e-1), (0.0, 1e-3)),
             DEPTH_LAYERS: ((1, 2), (1, 2)),
             WAVE_SAMPLES: ((0, 1, 4, 16), (0, 4)),
             WAVE_AREA_SAMPLES: AREA_SAMPLES_SWEEP,
             WAVE_HIT_AREA_SAMPLES: HIT_AREA_SAMPLES_SWEEP}
    reference = {"mirror": 15, "glossy": 12}  # below BVH `reflections` (30) / `glossy` (30, 20)

    def passes(self):  # the quadtree pass is a core one (the visits view uses it too)
        return [TraceEffectPass(self)]


register(ScreenSpaceReflections())
