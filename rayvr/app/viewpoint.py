"""Where a scene is first seen from, when neither its file (a glTF camera) nor --pose says: inside it
when it encloses the space round its centre (a room, a nave), at eye height on its floor and gazing
at its content; else from outside, framing its bounds (StereoRig.for_scene).

A scene encloses its centre when at least ENCLOSED_HITS of VIEW_RAYS rays from the centre of its
bounds meet a surface, and at least FACING_SHARE meet one that faces them: an interior's walls face
inwards, while from inside a closed object every surface faces away. Measured (128 rays, met /
facing): Sponza 0.94 / 0.94 (its courtyard is open), the built-in room 1.0 / 0.85 (it has a camera
of its own), the Cornell boxes 0.84-0.86 / the same (one side open: their classic view is from
outside, through it), the duck and the damaged helmet 1.0 / 0.0."""
from __future__ import annotations

import functools
import logging
import math

import numpy as np

from ..frame.cameras.rig import Pose, StereoRig
from ..scene.content import content_triangles, draw_points, triangles

VIEW_RAYS = 128
ENCLOSED_HITS, FACING_SHARE = 0.9, 0.5
EYE_HEIGHT = 1.6  # metres above the floor, or half the free height where the space is lower
CLEARANCE = 0.02  # of the bounds' diagonal: the centre must be this far from every surface
GAZE_DRAWS = 64  # content points tried for the first gaze (seeded: the same view every time)
MAX_GAZE_PITCH_DEG = 20.0
MIN_GAZE_DISTANCE = 0.05  # of the bounds' diagonal
log = logging.getLogger(__name__)


def sphere_directions(n: int) -> np.ndarray:
    """`n` unit directions spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    polar, turn = np.arccos(1.0 - 2.0 * i / n), math.pi * (1.0 + 5.0 ** 0.5) * i
    return np.stack([np.cos(turn) * np.sin(polar), np.cos(polar), np.sin(turn) * np.sin(polar)], axis=1)


class SceneView:
    """The scene with what casting rays through it needs (its BVH, built once a process)."""

    def __init__(self, scene):
        from ..accel.scene import kept_scene_bvh

        self.scene = scene
        self.bvh = kept_scene_bvh(scene, "sah")
        self.tri, self.normal, self.area = triangles(scene)
        lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
        self.centre, self.diagonal = (lo + hi) / 2, float(np.linalg.norm(hi - lo))

    def cast(self, origins, directions) -> tuple[np.ndarray, np.ndarray]:
        """(triangle or -1, distance or inf) of the first surface along each ray."""
        from ..accel.bvh import trace_reference

        origins = np.broadcast_to(np.asarray(origins, np.float64), np.shape(directions))
        prim, t, _, _ = trace_reference(self.bvh, origins - self.scene.origin, np.asarray(directions, np.float64))
        prim, t = np.asarray(prim, np.int64), np.asarray(t, np.float64)
        hit = np.isfinite(t) & (prim >= 0) & (prim < len(self.tri))
        return np.where(hit, prim, -1), np.where(hit, t, np.inf)

    @functools.cached_property
    def enclosed_shares(self) -> tuple[float, float]:
        """The shares of VIEW_RAYS rays from the bounds' centre that meet a surface, and one facing them."""
        d = sphere_directions(VIEW_RAYS)
        prim, _ = self.cast(self.centre, d)
        hit = prim >= 0
        facing = np.zeros(len(d), bool)
        facing[hit] = np.sum(self.normal[prim[hit]] * d[hit], axis=1) < 0
        return float(hit.mean()), float(facing.mean())

    def encloses(self) -> bool:
        if not len(self.tri):
            return False
        met, facing = self.enclosed_shares
        return met >= ENCLOSED_HITS and facing >= FACING_SHARE

    def inside_pose(self) -> Pose | None:
        """A head at eye height over the floor below the bounds' centre, gazing at a visible point of
        the content (or along the longest free horizontal line); None where the centre is not free
        space (inside an object, against a wall)."""
        c = self.centre
        axes = np.vstack([np.eye(3), -np.eye(3)])
        _, free = self.cast(c, axes)
        if not (free.min() > CLEARANCE * self.diagonal) or not np.isfinite(free[4]):  # [4]: straight down
            return None
        floor = c[1] - free[4]
        head = np.array([c[0], floor + min(EYE_HEIGHT, 0.5 * (free[4] + min(free[1], free[4] * 4))), c[2]])
        target = self.gaze(head)
        if target is None:  # the longest free horizontal line
            around = np.array([[math.cos(a), 0.0, -math.sin(a)] for a in np.linspace(0, 2 * math.pi, 16, endpoint=False)])
            _, reach = self.cast(head, around)
            reach = np.where(np.isfinite(reach), reach, self.diagonal)
            target = head + around[int(np.argmax(reach))]
        return Pose.look_at(head, target)

    def gaze(self, head) -> np.ndarray | None:
        """The first of GAZE_DRAWS content points (area-weighted, seeded) seen from `head` within
        +-MAX_GAZE_PITCH_DEG of level and at least MIN_GAZE_DISTANCE away, or None."""
        ok = content_triangles(self.scene)
        if not ok.any():
            return None
        ids = np.flatnonzero(ok)
        cdf = np.cumsum(self.area[ids])
        _, points = draw_points(self.tri, ids, cdf / cdf[-1], np.random.default_rng(0), GAZE_DRAWS)
        d = points - head
        dist = np.linalg.norm(d, axis=1)
        unit = d / np.maximum(dist, 1e-300)[:, None]
        _, seen_at = self.cast(head, unit)
        ok = ((dist >= MIN_GAZE_DISTANCE * self.diagonal) & (np.abs(unit[:, 1]) <= math.sin(math.radians(MAX_GAZE_PITCH_DEG)))
              & (seen_at >= dist - 1e-3 * self.diagonal))
        return points[int(np.argmax(ok))] if ok.any() else None


def first_view(scene, view: SceneView | None = None) -> tuple[str, Pose | None]:
    """(how the scene is first seen: "its camera", "inside" or "outside", the inside pose or None);
    `view`: the scene's SceneView where the caller has one."""
    if scene.camera is not None:
        return "its camera", None
    view = view or SceneView(scene)
    pose = view.inside_pose() if view.encloses() else None
    return ("inside", pose) if pose is not None else ("outside", None)


def first_rig(scene, size, first: tuple | None = None, **kw) -> StereoRig:
    """The rig a scene is first seen through (the module's rule; `first`: first_view's answer where
    the caller has it); `kw` as StereoRig's. -v logs its pose in --pose syntax."""
    how, pose = first or first_view(scene)
    if pose is not None:
        kw.setdefault("near", max(scene.extent * 1e-4, 1e-6))
        rig = StereoRig(pose=pose, size=size, **kw)
    else:
        rig = StereoRig.for_scene(scene, size=size, **kw)
    log.info("first view (%s): --pose %s", how, pose_argument(rig.pose))
    return rig


def pose_argument(pose: Pose, distance: float = 1.0) -> str:
    """`pose` in --pose syntax (EX,EY,EZ,TX,TY,TZ): its position and a point `distance` ahead."""
    target = pose.position + distance * pose.forward
    return ",".join(f"{v:.4g}" for v in (*pose.position, *target))
