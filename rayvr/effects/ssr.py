"""`ssr`: mirror reflections traced in screen space through the depth quadtree (Widmer et al. 2015,
rayvr/passes/quadtree.py) instead of the BVH; a ray the quadtree cannot answer (it leaves the
image, heads for the camera, or crosses the image without a hit) falls back to the BVH when
`fallback` is 1, else sees the background. The pixel event is the `reflections` one (direct light
with shadow rays, a Fresnel-weighted mirror path); the hit found on screen is shaded like a BVH
hit (its own direct light and shadows). Single depth layer: a ray that reaches a pixel already
more than `thickness` (relative depth) behind its surface passed behind that object, and what it
meets there is hidden from the screen: that ray too goes to the fallback (thickness 1e30: pure
height-field semantics).

Missing (issue 10): a second depth layer with occlusion volumes, GGX-glossy rays, warp, DoF."""
import math

from .base import Effect, Param, register
from .shadows import AREA_SAMPLES, AREA_SAMPLES_SWEEP

COS = {deg: math.cos(math.radians(deg)) for deg in (3, 10, 25)}


class ScreenSpaceReflections(Effect):
    name = "ssr"
    id = 2
    doc = "+ screen-space mirror reflections through the depth quadtree, BVH fallback"
    params = {
        "gamma_norm": Param(float, COS[10], 0.0, 1.0, "quadtree plane merge: cosine of the largest normal angle "
                                                        "(1 = lossless)"),
        "gamma_dist": Param(float, 1e-3, 0.0, 1.0, "quadtree plane merge: largest relative depth error (0 = lossless)"),
        "fallback": Param(int, 1, 0, 1, "1: trace in the BVH what the screen cannot answer; 0: the background"),
        "thickness": Param(float, 0.02, 0.0, 1e30, "a screen hit counts only if the ray is within this relative "
                                                    "depth behind the surface there (else it passed behind it)"),
        "bounces": Param(int, 1, 1, 4, "reflection bounces (each traced in screen space first)"),
        "area_samples": AREA_SAMPLES,
    }
    traced = True
    denoised = False  # mirror reflections are sharp detail, not noise: --denoise leaves them
    reflective = True
    uses_quadtree = True
    shader = "effects/reflections.glsl"  # the same pixel event as `reflections`: one mirror path
    sweep = {"gamma_norm": ((1.0, COS[3], COS[10], COS[25]), (1.0, COS[10])),
             "thickness": ((0.005, 0.02, 0.1, 1e30), (0.02, 1e30)),
             "gamma_dist": ((0.0, 1e-5, 1e-3, 1e-1), (0.0, 1e-3)),
             "area_samples": AREA_SAMPLES_SWEEP}
    reference = {"mirror": 15}  # models mirrors, less than BVH `reflections` (30) or `glossy` (20)

    def passes(self):  # the quadtree pass is a core one (the visits view uses it too)
        from ..passes.trace_effect import TraceEffectPass
        return [TraceEffectPass(self)]


register(ScreenSpaceReflections())
