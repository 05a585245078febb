"""`photon`: direct light with shadow rays (as `shadows`) plus photon-mapped indirect light and
caustics in place of the constant ambient term (photon-mapping paper, in ../shared/papers/).

Per frame, for both eyes at once (one photon map a frame):
  photon_trace   photons from the lights in proportion to power, through mirror/glossy bounces,
                 stored on diffuse surfaces (trace.py)
  photon_cells   the hash grid's cell per photon and the counts per cell (cell = radius)
  photon_scan    the counts' exclusive prefix sum: start index per cell
  photon_sort    the photons sorted by cell (GPU radix sort): the photon map
  photon_kdtree  the kd-tree baseline, built on the CPU (only for the kd-tree estimators)
  rt_photon      each pixel: direct light + albedo / pi * irradiance from the photons within
                 `radius` (estimator: all of them, or the k nearest with a heap)
The photon count, bounces and grid cell are the largest over the `photon` materials; each material
searches with its own radius and estimator. The passes are this package's modules (trace, cells,
scan, sort, kdtree, shade), their shared settings setup.py.
"""
from __future__ import annotations

from ....accel.photon_map import ESTIMATORS, MAX_K
from ...effect_registry import Effect, Param, register
from ...passes.trace_effect import WAVE_AREA_SAMPLES
from ..shadows import AREA_SAMPLES
from .cells import PhotonCellsPass
from .kdtree import PhotonKdTreePass
from .scan import PhotonScanPass
from .setup import DEFAULTS
from .shade import PhotonShadePass
from .sort import PhotonSortPass
from .trace import PhotonTracePass


class PhotonEffect(Effect):
    name = "photon"
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
              WAVE_AREA_SAMPLES: AREA_SAMPLES}
    traced = True
    shader = "effects/photon.glsl"  # its part of the wavefront pixel event (rt/wave_shade.comp)
    # `rayvr bench tradeoff`: the paper's photon counts (128^2 .. 512^2) and radii (0.02 .. 0.2 scene
    # units, as the paper's), the heap, and the stored bounces; --quick renders one of each.
    sweep = {"photons": ((16384, 65536, 262144), (16384,)),
             "radius": ((0.02, 0.05, 0.1, 0.2), (0.1,)),
             "estimator": ((0, 1), (1,)),
             "bounces": ((2, 3, 4, 6), (2,))}
    # Not the reference for any class: a density estimate is biased (blurred by its radius); the
    # converged reference for indirect light is path tracing. `rayvr bench photon` judges it
    # against a many-photon map with another seed instead.
    reference = {}

    def passes(self):
        return [PhotonTracePass(), PhotonCellsPass(), PhotonScanPass(), PhotonSortPass(), PhotonKdTreePass(),
                PhotonShadePass(self)]


register(PhotonEffect())
