"""What the photon effect's frame-level passes share: the frame's photon map settings from the
`photon` materials (`photon_setup`), and the base of its passes (`PhotonPass`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....accel.photon_map import GridShape, grid_shape
from ...graph import FramePlan, Pass

# bounces 4: the transport depth of `path`'s default and of the converged reference (4 bounces after
# the pixel's surface); at 3, Sponza's indirect light was 0.85 of path's (2x64x72, llvmpipe), at 4 0.97
DEFAULTS = {"photons": 65536, "radius": 0.1, "estimator": 0, "k": 32, "bounces": 4, "map_seed": 0}


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
