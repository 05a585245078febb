"""Light selection for shadow rays (`--light-picks K`): instead of lighting every surface with
every light (a shadow ray per point or directional light, `area_samples` rays per rect light), a
traced effect draws K lights per surface, each with probability proportional to its power, and
divides each drawn light's contribution by K times that probability: next-event estimation that
picks lights by power (Shirley, Wang and Zimmerman 1996). Unbiased: the expectation of each draw is
the sum over all lights. A scene of many lights then costs K lights' rays per surface instead of
all of theirs; with few lights it only adds noise. 0, the default: every light, as before.

The picks are drawn from the surface's own random stream (glsl/rt/shadow_rays.glsl
light_samples_begin), so both eyes pick the same lights for the same point. The probabilities ride
in the light records (scene/gpu_scene.py): radiance.w the light's probability, direction.w the
running sum up to it, which glsl/common/scene.glsl pick_light searches.
"""
from __future__ import annotations

import math

import numpy as np

from ..render_options.light_selection import SHADOW_PROBES


LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709: the power a light's colour carries


def light_flux(light, scene_radius: float) -> np.ndarray:
    """The light's emitted power (rgb flux): a point light's intensity over the sphere (4 pi I), a
    rect light's radiance over its area and hemisphere (pi L A, twice when two-sided), a
    directional light's irradiance over the scene's cross-section (E pi r^2, r the radius of the
    scene's bounding sphere: all of its light that can reach the scene). The photon map emits by it too."""
    rad = np.asarray(light.color, np.float64) * light.intensity
    if light.kind == "point":
        return 4.0 * math.pi * rad
    if light.kind == "rect":
        area = 4.0 * float(np.linalg.norm(np.cross(light.u, light.v)))
        return math.pi * rad * area * (2.0 if light.two_sided else 1.0)
    if light.kind == "directional":
        return rad * math.pi * scene_radius ** 2
    raise ValueError(f"unknown light kind {light.kind!r}")


def light_power(light, scene_radius: float) -> float:
    """light_flux in luminance units."""
    return float(np.dot(light_flux(light, scene_radius), LUMINANCE))


def pick_table(lights, scene_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(probability of each light, running sum up to and including it), float32: proportional to
    light_power (a light of no power is never drawn; all without power: uniform). The last sum is
    exactly 1, so a uniform number in [0, 1) always finds a light."""
    power = np.array([max(light_power(li, scene_radius), 0.0) for li in lights], np.float64)
    if len(power) == 0:
        return np.zeros(0, np.float32), np.zeros(0, np.float32)
    total = power.sum()
    pmf = power / total if total > 0 and np.isfinite(total) else np.full(len(power), 1.0 / len(power))
    cdf = np.cumsum(pmf)
    cdf[-1] = 1.0
    return pmf.astype(np.float32), cdf.astype(np.float32)


def shadow_rays_per_surface(lights, per_rect: int, picks: int) -> int:
    """The most shadow rays one surface stores (the wavefront's slots): every light's (`per_rect`
    points a rect light, one another), or with `picks` lights drawn, picks times the most one
    light takes (the same light may be drawn again)."""
    if picks > 0 and lights:
        return picks * max(per_rect if light.kind == "rect" else 1 for light in lights)
    return sum(per_rect if light.kind == "rect" else 1 for light in lights) or 1
