"""Seeded random head poses inside a benchmark scene (`rayvr bench vr`): where a headset's wearer
stands and looks, instead of the one fixed view of rayvr/bench/scenes.py that the other benches time.

A pose is drawn uniformly: the head's floor position inside the scene's walkable region (REGIONS),
its eye height above that floor (EYE_HEIGHT_M), its yaw over the whole turn and its pitch within
+-MAX_PITCH_DEG; no roll, so the eyes stay level, the rig's IPD apart along the head's horizontal
right axis (StereoRig.eye). The draws come from a generator seeded with the bench's seed and the
scene's name: a scene's poses depend on the seed alone, not on which other scenes a run measures.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from ..frame.cameras.rig import Pose

POSE_SEED = 22  # the default seed (the number): fixed, so runs on different days time the same heads
MAX_PITCH_DEG = 20.0  # a seated or standing user looks about this far up or down while moving the head
EYE_HEIGHT_M = (1.5, 1.8)  # standing adults' eye heights above the floor, metres


@dataclass(frozen=True)
class PoseRegion:
    """Where a scene's heads may stand, from its bounding box: the box's central `span` (fractions of
    its half-widths along x and z around the box's centre) on a floor `floor_above_box` metres above
    the box's bottom. `what` says why those numbers, for the report."""

    span: tuple[float, float]
    floor_above_box: float
    what: str


REGIONS = {
    # The room's box is its walls, floor and ceiling (8 x 3.2 x 8 m); its furniture stays below 1.4 m.
    "default": PoseRegion((0.85, 0.85), 0.0, "the room, 0.6 m from each wall, on its floor (the box's bottom)"),
    # Sponza's box (34.8 x 16.6 x 15.6 m) holds the side aisles and the ground plane 1 m under the
    # courtyard: the nave lies between the colonnades (the pillars' inner faces at |z| >= 2.06 m of
    # the box's 7.8, the last pillars at |x| = 11.6 m of 17.4), its arches from 2.69 m up.
    "sponza": PoseRegion((0.6, 0.2), 1.0, "Sponza's nave between the colonnades (|z| <= 1.56 m, 0.5 m clear of "
                                          "the pillars; |x| <= 10.4 m), on its floor 1 m above the box's bottom"),
}


def head_rotation(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """Camera-to-world rotation of a level head: turned `yaw_deg` about +Y (0 looks along -Z,
    positive turns left, counter-clockwise seen from above), then tilted `pitch_deg` about its
    right axis (positive looks up)."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    turn = np.array([[math.cos(y), 0.0, math.sin(y)], [0.0, 1.0, 0.0], [-math.sin(y), 0.0, math.cos(y)]])
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(p), -math.sin(p)], [0.0, math.sin(p), math.cos(p)]])
    return turn @ tilt


@dataclass(frozen=True)
class HeadPose:
    """One drawn head: `position` the point between the eyes (world metres), yaw and pitch in degrees
    (head_rotation)."""

    index: int
    position: tuple[float, float, float]
    yaw_deg: float
    pitch_deg: float

    @property
    def pose(self) -> Pose:
        return Pose(np.asarray(self.position, dtype=np.float64), head_rotation(self.yaw_deg, self.pitch_deg))

    def to_dict(self) -> dict:
        return {"index": self.index, "position": list(self.position), "yaw_deg": self.yaw_deg,
                "pitch_deg": self.pitch_deg}


def region(name: str) -> PoseRegion:
    if name not in REGIONS:
        raise ValueError(f"bench vr has no head-pose region for scene {name!r}; it knows {', '.join(REGIONS)}")
    return REGIONS[name]


def pose_bounds(scene, name: str) -> dict:
    """The box the drawn heads' centres lie in: {"x": [lo, hi], "y": ..., "z": ...}, world metres."""
    reg = region(name)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in scene.bounds)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    floor = lo[1] + reg.floor_above_box
    return {"x": [centre[0] - reg.span[0] * half[0], centre[0] + reg.span[0] * half[0]],
            "y": [floor + EYE_HEIGHT_M[0], floor + EYE_HEIGHT_M[1]],
            "z": [centre[2] - reg.span[1] * half[2], centre[2] + reg.span[1] * half[2]]}


def draw_poses(scene, name: str, count: int, seed: int) -> list[HeadPose]:
    """`count` head poses inside scene `name`'s region (pose_bounds), from `seed`."""
    if count < 1:
        raise ValueError(f"--poses: a bench over random head poses needs at least one, got {count}")
    bounds = pose_bounds(scene, name)
    rng = np.random.default_rng([seed, zlib.crc32(name.encode())])
    out = []
    for i in range(count):
        position = tuple(float(rng.uniform(*bounds[axis])) for axis in ("x", "y", "z"))
        yaw = float(rng.uniform(0.0, 360.0))
        pitch = float(rng.uniform(-MAX_PITCH_DEG, MAX_PITCH_DEG))
        out.append(HeadPose(i, position, yaw, pitch))
    return out
