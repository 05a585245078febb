"""Seeded head poses inside a benchmark scene (`rayvr bench vr`, `tradeoff`, `budget`, `lights`):
where a headset's wearer stands and looks, instead of the one fixed view of rayvr/bench/scenes.py
that the other benches time.

Every pose's head stands at a point drawn uniformly in the scene's walkable region (REGIONS), its
eye height above that floor within EYE_HEIGHT_M; no roll, so the eyes stay level, the rig's IPD
apart along the head's horizontal right axis (StereoRig.eye). Poses come in two kinds, alternating
(pose_kind):

- even indices, `content`: the head gazes at a point of the scene's content, so the pose measures
  something a user looks at. The point is drawn area-weighted over the triangles that are neither
  the scene's enclosing shell (rayvr/scene/content.py: its walls, floors and ceilings) nor emitters (a
  light is drawn raster and its glare says nothing about the effects); it must be visible from the
  head (no triangle in between, a CPU ray cast through the scene's BVH), at least MIN_TARGET_M
  away, seen at most MAX_GRAZING_DEG from its surface's normal (a surface seen edge-on fills no
  pixel) and within +-MAX_GAZE_PITCH_DEG of level (a user does not stare at the floor under the
  feet or straight up); head and point are drawn again, up to TARGET_DRAWS times, else a
  ValueError says why. Yaw and pitch put the point on the view axis through the point between the
  eyes, at the image's centre (no offset: a random aim off the point would only look past small
  objects);
- odd indices, `random`: yaw over the whole turn, pitch within +-MAX_PITCH_DEG, as every pose was
  before content poses came: random pose k (index 2k + 1) is the pose k of that older scheme, drawn
  from the same stream, so its figures still compare.

The draws come from generators seeded with the bench's seed and the scene's name (content pose k
from one of its own): a scene's poses depend on the seed alone, not on which other scenes a run
measures, and pose I is the same however many are drawn.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from ..frame.cameras.rig import Pose
from ..scene.content import content_triangles, draw_points

POSE_SEED = 22  # the default seed: fixed, so runs on different days time the same heads
MAX_PITCH_DEG = 20.0  # a seated or standing user looks about this far up or down while moving the head
EYE_HEIGHT_M = (1.5, 1.8)  # standing adults' eye heights above the floor, metres
POSE_KINDS = ("content", "random")  # pose I's kind: POSE_KINDS[I % 2]
# How poses are drawn, for the reports' meta: a folder's earlier rows stand beside new ones only when
# they were drawn the same way (before content poses every pose was random, under the same seed).
POSE_SCHEME = "even content, odd random"

# A content pose's gaze (draw_poses)
MIN_TARGET_M = 0.75  # nearer than this a point fills the view; the eyes' parallax grows with 1 / distance
MAX_GAZE_PITCH_DEG = 60.0
MAX_GRAZING_DEG = 80.0
TARGET_DRAWS = 256  # (head, point) draws a content pose may take, TARGET_BATCH at a time (one ray cast each)
TARGET_BATCH = 16
VISIBLE_SLACK_M = 1e-3  # a hit this close before the point is the point's own surface (or its neighbour's)


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


def gaze_angles(direction) -> tuple[float, float]:
    """(yaw, pitch) in degrees that head_rotation turns the view axis (-Z) to `direction`; yaw in [0, 360)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    yaw = math.degrees(math.atan2(-d[0], -d[2])) % 360.0
    return (0.0 if yaw == 360.0 else yaw), math.degrees(math.asin(max(-1.0, min(1.0, float(d[1])))))


def pose_kind(index: int) -> str:
    """Pose `index`'s kind: content poses at even indices, random ones at odd."""
    return POSE_KINDS[index % 2]


@dataclass(frozen=True)
class HeadPose:
    """One drawn head: `position` the point between the eyes (world metres), yaw and pitch in degrees
    (head_rotation); `kind` (POSE_KINDS) and, for a content pose, the `target` it gazes at (world)."""

    index: int
    position: tuple[float, float, float]
    yaw_deg: float
    pitch_deg: float
    kind: str = "random"
    target: tuple[float, float, float] | None = None

    @property
    def pose(self) -> Pose:
        return Pose(np.asarray(self.position, dtype=np.float64), head_rotation(self.yaw_deg, self.pitch_deg))

    @property
    def label(self) -> str:
        """"3 (random)": the index with its kind, as reports name a pose."""
        return f"{self.index} ({self.kind})"

    def to_dict(self) -> dict:
        out = {"index": self.index, "kind": self.kind, "position": list(self.position), "yaw_deg": self.yaw_deg,
               "pitch_deg": self.pitch_deg}
        if self.target is not None:
            out["target"] = list(self.target)
        return out


def pose_label(pose: dict) -> str:
    """A row's pose (HeadPose.to_dict) as reports name it: "3 (random)" (rows from before kinds: "3")."""
    return f"{pose['index']} ({pose['kind']})" if "kind" in pose else str(pose["index"])


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


def _random_pose(rng, bounds: dict, index: int) -> HeadPose:
    """The next random pose of `rng`: five draws, position, yaw, pitch (the older scheme's, in its order)."""
    position = tuple(float(rng.uniform(*bounds[axis])) for axis in ("x", "y", "z"))
    yaw = float(rng.uniform(0.0, 360.0))
    pitch = float(rng.uniform(-MAX_PITCH_DEG, MAX_PITCH_DEG))
    return HeadPose(index, position, yaw, pitch, "random")


class _Gaze:
    """What a scene's content poses draw from: its content triangles (area-weighted), and its
    SceneView (app/viewpoint.py: the renderer's BVH, built once a process) to cast the sight line."""

    def __init__(self, scene, name: str):
        from ..app.viewpoint import SceneView

        self.view = SceneView(scene)
        ok = content_triangles(scene)
        if not ok.any():
            raise ValueError(f"scene {name!r} has no content to gaze at: every triangle is its shell "
                             f"(walls, floors, ceilings) or emissive")
        self.ids = np.flatnonzero(ok)
        self.cdf = np.cumsum(self.view.area[self.ids])
        self.cdf /= self.cdf[-1]
        self.tri, self.normal = self.view.tri, self.view.normal

    def points(self, rng, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(triangle ids, points) of `n` points drawn uniformly over the content's area."""
        return draw_points(self.tri, self.ids, self.cdf, rng, n)

    def visible(self, heads: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Whether the first surface on the ray from each head towards its point is the point's."""
        d = points - heads
        dist = np.linalg.norm(d, axis=1)
        _, t = self.view.cast(heads, d / dist[:, None])
        return t >= dist - VISIBLE_SLACK_M


def _content_pose(gaze: _Gaze, bounds: dict, index: int, rng, name: str) -> HeadPose:
    """A content pose (the module's rules): heads and points drawn TARGET_BATCH at a time, the
    first pair in draw order that passes every test."""
    why = {"nearer than MIN_TARGET_M": 0, "pitch beyond MAX_GAZE_PITCH_DEG": 0, "seen edge-on": 0, "hidden": 0}
    for _ in range(TARGET_DRAWS // TARGET_BATCH):
        heads = np.stack([rng.uniform(*bounds[axis], TARGET_BATCH) for axis in ("x", "y", "z")], axis=1)
        ids, points = gaze.points(rng, TARGET_BATCH)
        d = points - heads
        dist = np.linalg.norm(d, axis=1)
        unit = d / np.maximum(dist, 1e-300)[:, None]
        near = dist < MIN_TARGET_M
        steep = np.abs(unit[:, 1]) > math.sin(math.radians(MAX_GAZE_PITCH_DEG))
        grazing = np.abs(np.sum(unit * gaze.normal[ids], axis=1)) < math.cos(math.radians(MAX_GRAZING_DEG))
        ok = ~near & ~steep & ~grazing
        seen = np.zeros(TARGET_BATCH, bool)
        if ok.any():
            seen[ok] = gaze.visible(heads[ok], points[ok])
        for k, v in (("nearer than MIN_TARGET_M", near), ("pitch beyond MAX_GAZE_PITCH_DEG", ~near & steep),
                     ("seen edge-on", ~near & ~steep & grazing), ("hidden", ok & ~seen)):
            why[k] += int(v.sum())
        if seen.any():
            i = int(np.argmax(seen))
            yaw, pitch = gaze_angles(unit[i])
            return HeadPose(index, tuple(float(x) for x in heads[i]), yaw, pitch, "content",
                            tuple(float(x) for x in points[i]))
    raise ValueError(f"scene {name!r}: content pose {index} found no visible point of the scene's content in "
                     f"{TARGET_DRAWS} draws of head and point ("
                     + ", ".join(f"{k}: {v}" for k, v in why.items()) + ")")


def draw_poses(scene, name: str, count: int, seed: int) -> list[HeadPose]:
    """`count` head poses inside scene `name`'s region (pose_bounds), from `seed`: content poses at
    even indices, random ones at odd (the module's docstring)."""
    if count < 1:
        raise ValueError(f"--poses: a bench over head poses needs at least one, got {count}")
    bounds = pose_bounds(scene, name)
    key = zlib.crc32(name.encode())
    rng = np.random.default_rng([seed, key])  # the random poses' stream, as before content poses came
    gaze = _Gaze(scene, name)
    out = []
    for i in range(count):
        if pose_kind(i) == "random":
            out.append(_random_pose(rng, bounds, i))
        else:  # a generator of its own: how many draws pose k takes moves no other pose
            out.append(_content_pose(gaze, bounds, i, np.random.default_rng([seed, key, 1, i // 2]), name))
    return out
