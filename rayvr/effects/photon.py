"""`photon`: direct light with shadow rays (as `shadows`) plus photon-mapped indirect light and
caustics in place of the constant ambient term (photon-mapping paper, in ../shared/papers/).

Per frame, for both eyes at once (one photon map a frame):
  photon_trace   photons from the lights in proportion to power, through mirror/glossy bounces,
                 stored on diffuse surfaces (passes/photon_trace.py)
  photon_cells   the hash grid's cell per photon and the counts per cell (cell = radius)
  photon_scan    the counts' exclusive prefix sum: start index per cell
  photon_sort    the photons sorted by cell (GPU radix sort): the photon map
  photon_kdtree  the kd-tree baseline, built on the CPU (only for the kd-tree estimators)
  rt_photon      each pixel: direct light + albedo / pi * irradiance from the photons within
                 `radius` (estimator: all of them, or the k nearest with a heap)
The photon count, bounces and grid cell are the largest over the `photon` materials; each material
searches with its own radius and estimator.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..accel.photon_map import ESTIMATORS, MAX_K, GridShape, grid_shape
from ..frame import FramePlan, Pass
from .base import Effect, Param, register
from .shadows import AREA_SAMPLES

DEFAULTS = {"photons": 65536, "radius": 0.1, "estimator": 0, "k": 32, "bounces": 3, "map_seed": 0}


@dataclass(frozen=True)
class PhotonSetup:
    paths: int  # photon paths emitted
    stores: int  # photons a path may store (= bounces)
    grid: GridShape
    kdtree: bool  # some material searches the kd-tree
    estimators: int  # bit i: some material uses estimator i (rt_photon compiles only those)
    sphere: tuple  # the scene's bounding sphere (scene-local centre, radius)
    map_seed: int = 0  # mixed into the frame seed for the photon map alone (the pixels' samples keep theirs)

    @property
    def slots(self) -> int:
        return self.paths * self.stores

    def seed(self, frame_seed: int) -> int:
        return ((int(frame_seed) + 0x2545F491 * self.map_seed) * 0x9E3779B1 + 0x632BE5AB) & 0xFFFFFFFF


_BOUNDS: list = [None, None]  # the vertex array last asked about, its scene-local bounds


def _local_bounds(scene) -> np.ndarray:
    """Scene-local bounds of the vertices, cached per vertex array (moving geometry brings a new one)."""
    v = scene.vertices
    if _BOUNDS[0] is not v:
        _BOUNDS[:] = [v, np.stack([v.min(0), v.max(0)]).astype(np.float64) if len(v) else np.zeros((2, 3))]
    return _BOUNDS[1]


def photon_setup(sizing) -> PhotonSetup:
    """The frame's photon map settings from the materials that use `photon` (the largest photon
    count, bounces and radius; a kd-tree if any material asks for one)."""
    ps = [a.params for a in sizing.assignments if a.effect == "photon"] or [{}]
    get = lambda k: [p.get(k, DEFAULTS[k]) for p in ps]
    lo, hi = _local_bounds(sizing.scene)
    scale = float(np.linalg.norm(hi - lo)) or 1.0
    radius = max(get("radius"))
    return PhotonSetup(paths=int(max(get("photons"))), stores=int(max(get("bounces"))),
                       grid=grid_shape(lo, hi, radius), kdtree=any(e >= 2 for e in get("estimator")),
                       estimators=sum(1 << e for e in set(get("estimator"))),
                       sphere=tuple(float(x) for x in (lo + hi) / 2) + (0.5 * scale,),
                       map_seed=int(max(get("map_seed"))))


class PhotonPass(Pass):
    """A pass of the photon map: needed when a material uses `photon`; `role` says what it makes."""

    role = ""

    def why(self, plan: FramePlan) -> str | None:
        return f"effect photon: {self.role}" if "photon" in plan.effects else None


class PhotonEffect(Effect):
    name = "photon"
    id = 6
    doc = "+ photon-mapped indirect light and caustics (GPU hash-grid photon map)"
    params = {"photons": Param(int, DEFAULTS["photons"], 256, 1 << 22, "photon paths emitted per frame"),
              "radius": Param(float, DEFAULTS["radius"], 1e-4, 100.0, "search radius in scene units (metres); "
                                                                    "the paper's 0.02-0.2"),
              "estimator": Param(int, DEFAULTS["estimator"], 0, len(ESTIMATORS) - 1,
                                 "density estimate: " + ", ".join(f"{i} {e}" for i, e in enumerate(ESTIMATORS))),
              "k": Param(int, DEFAULTS["k"], 1, MAX_K, "photons the heap keeps (estimators grid_heap, kdtree_heap)"),
              "bounces": Param(int, DEFAULTS["bounces"], 1, 8, "photons a path stores at most (diffuse bounces)"),
              "map_seed": Param(int, DEFAULTS["map_seed"], 0, 1 << 30,
                                "another photon map for the same frame seed (direct light unchanged)"),
              "area_samples": AREA_SAMPLES}
    traced = True
    shader = "effects/photon.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    # `rayvr bench tradeoff`: the paper's photon counts (128^2 .. 512^2) and radii (0.02 .. 0.2 scene
    # units, as the paper's), and the heap; --quick renders one of each.
    sweep = {"photons": ((16384, 65536, 262144), (16384,)),
             "radius": ((0.02, 0.05, 0.1, 0.2), (0.1,)),
             "estimator": ((0, 1), (1,))}
    # Not the reference for any class: a density estimate is biased (blurred by its radius); the
    # converged reference for indirect light is path tracing. `rayvr bench photon` judges it
    # against a many-photon map with another seed instead.
    reference = {}

    def passes(self):
        from ..passes.photon_cells import PhotonCellsPass
        from ..passes.photon_kdtree import PhotonKdTreePass
        from ..passes.photon_scan import PhotonScanPass
        from ..passes.photon_shade import PhotonShadePass
        from ..passes.photon_sort import PhotonSortPass
        from ..passes.photon_trace import PhotonTracePass
        return [PhotonTracePass(), PhotonCellsPass(), PhotonScanPass(), PhotonSortPass(), PhotonKdTreePass(),
                PhotonShadePass(self)]


register(PhotonEffect())
