"""Seeded head trajectories inside a benchmark scene: how a headset's wearer moves, frame by frame,
so the trade between speed and error can be judged in motion and not on still frames.

Every trajectory starts at a content pose of rayvr/bench/head_poses.py (its anchor: a head inside
the scene gazing at its content) and runs `seconds` at a display rate (90 or 120 Hz), one pose a
frame at t = k / rate. Its kind (KINDS) is one of the motions a user makes:

- `slow_look`: the head turns at SLOW_LOOK_DEG_S about the vertical, easing in and out over
  EASE_S at both ends (a user reading the scene);
- `fast_turn`: a turn of FAST_TURN_DEG whose speed peaks at FAST_TURN_PEAK_DEG_S, on the
  minimum-jerk profile of a head movement (Flash and Hogan 1985), then a hold;
- `walk`: the head walks at WALK_M_S along the floor (forward to its target if there is room, else
  back or to a side, whichever stays in the scene's region) keeping its gaze on the target, with a
  vertical bob of BOB_M at STEP_HZ;
- `glance`: a look GLANCE_DEG aside and back (minimum jerk out over GLANCE_S, a hold of GLANCE_HOLD_S,
  back), as to something at the edge of view.

The turn's direction and the walk's are drawn from generators seeded with the seed, the scene's
name and the trajectory's index, so the same kinds and seed give the same trajectories, and each is
the same motion at both rates (the pose at t is the same at 90 and 120 Hz). A recorded camera path
(the preview's P) is a trajectory too (`from_path`).
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from ..frame.cameras.rig import Pose, load_path
from .head_poses import MIN_TARGET_M, POSE_SEED, HeadPose, draw_poses, gaze_angles, head_rotation, pose_bounds

KINDS = ("slow_look", "fast_turn", "walk", "glance")
RATES_HZ = (90, 120)
SECONDS = 1.5
SLOW_LOOK_DEG_S = 30.0
EASE_S = 0.2
FAST_TURN_DEG = 90.0
# minimum jerk: the peak speed is 15/8 of the mean, so the turn lasts 15/8 * angle / peak (1.1 s)
FAST_TURN_PEAK_DEG_S = 150.0
WALK_M_S = 1.0
BOB_M = 0.02  # half the head's vertical travel over a step
STEP_HZ = 2.0
GLANCE_DEG = 30.0
GLANCE_S = 0.3  # out (and back): a peak of 15/8 * GLANCE_DEG / GLANCE_S = 188 deg/s
GLANCE_HOLD_S = 0.2


@dataclass(frozen=True)
class Trajectory:
    """One head motion: `poses` (the point between the eyes and the head's rotation) at `times`
    seconds, `rate_hz` frames a second; `kind` (KINDS, or "recorded"), its `anchor` pose."""

    kind: str
    rate_hz: float
    poses: tuple
    times: tuple
    anchor: HeadPose | None = None

    @property
    def label(self) -> str:
        where = f" from pose {self.anchor.label}" if self.anchor is not None else ""
        return f"{self.kind} at {self.rate_hz:g} Hz{where}"


def minimum_jerk(s):
    """The minimum-jerk profile from 0 to 1 over s in [0, 1] (position; 0 speed and acceleration at both ends)."""
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s)


def _times(seconds: float, rate_hz: float) -> np.ndarray:
    return np.arange(int(round(seconds * rate_hz)) + 1) / float(rate_hz)


def yaw_offsets(kind: str, t: np.ndarray, seconds: float) -> np.ndarray:
    """Degrees the head has turned from its anchor by times `t`, for the turning kinds (positive: left)."""
    if kind == "slow_look":
        return SLOW_LOOK_DEG_S * _eased_distance(t, seconds)
    if kind == "fast_turn":
        duration = 15.0 / 8.0 * FAST_TURN_DEG / FAST_TURN_PEAK_DEG_S
        return FAST_TURN_DEG * minimum_jerk(t / duration)
    if kind == "glance":
        out = GLANCE_DEG * minimum_jerk(t / GLANCE_S)
        back = GLANCE_S + GLANCE_HOLD_S
        return out - GLANCE_DEG * minimum_jerk((t - back) / GLANCE_S)
    raise ValueError(f"{kind!r} is not a turning trajectory")


def _eased_distance(t, seconds: float) -> np.ndarray:
    """Distance at unit top speed by times `t`: the speed rises from 0 to 1 over EASE_S on the
    minimum-jerk curve, holds, and falls the same way over the last EASE_S of `seconds`."""
    t = np.asarray(t, dtype=np.float64)
    ease = min(EASE_S, seconds / 2)

    def rise(x):  # the integral of minimum_jerk(u / ease) for u in [0, x], x in [0, ease]
        s = np.clip(x, 0.0, ease) / ease
        return ease * s ** 4 * (2.5 - 3.0 * s + s * s)
    return rise(t) + np.clip(t - ease, 0.0, None) - rise(t - (seconds - ease))


def _level(position, target) -> tuple[float, float]:
    return gaze_angles(np.asarray(target, dtype=np.float64) - np.asarray(position, dtype=np.float64))


def _walk_direction(anchor: HeadPose, bounds: dict, distance: float, rng) -> np.ndarray:
    """A horizontal unit direction to walk `distance` along that stays inside `bounds` and keeps the
    target at least MIN_TARGET_M away: forward to the target first, then back, then either side (in
    an order drawn from `rng`)."""
    p, target = np.asarray(anchor.position), np.asarray(anchor.target)
    forward = target - p
    forward[1] = 0.0
    forward /= max(np.linalg.norm(forward), 1e-12)
    right = np.array([-forward[2], 0.0, forward[0]])
    sides = [right, -right] if rng.random() < 0.5 else [-right, right]
    for d in [forward, -forward, *sides]:
        end = p + distance * d
        inside = all(bounds[a][0] <= end[i] <= bounds[a][1] for i, a in ((0, "x"), (2, "z")))
        if inside and np.linalg.norm(target - end) >= MIN_TARGET_M:
            return d
    raise ValueError(f"no walk of {distance:g} m from pose {anchor.label} stays in the scene's region")


def trajectory(kind: str, anchor: HeadPose, rate_hz: float, seconds: float, bounds: dict, rng) -> Trajectory:
    """The `kind` trajectory from content pose `anchor` (the module's docstring)."""
    if kind not in KINDS:
        raise ValueError(f"unknown trajectory kind {kind!r}; allowed: {', '.join(KINDS)}")
    if anchor.target is None:
        raise ValueError(f"pose {anchor.label} gazes at no target: a trajectory starts at a content pose")
    t = _times(seconds, rate_hz)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    p0 = np.asarray(anchor.position, dtype=np.float64)
    if kind == "walk":
        d = _walk_direction(anchor, bounds, WALK_M_S * seconds, rng)
        along = WALK_M_S * _eased_distance(t, seconds)
        bob = BOB_M * np.sin(2.0 * math.pi * STEP_HZ * t) * np.clip(along / max(WALK_M_S * EASE_S, 1e-9), 0, 1)
        positions = p0 + along[:, None] * d + bob[:, None] * np.array([0.0, 1.0, 0.0])
        poses = tuple(Pose(q, head_rotation(*_level(q, anchor.target))) for q in positions)
    else:
        yaw = anchor.yaw_deg + sign * yaw_offsets(kind, t, seconds)
        poses = tuple(Pose(p0.copy(), head_rotation(float(y), anchor.pitch_deg)) for y in yaw)
    return Trajectory(kind, float(rate_hz), poses, tuple(float(x) for x in t), anchor)


def draw_trajectories(scene, name: str, kinds=KINDS, rates=RATES_HZ, per_kind: int = 1, seconds: float = SECONDS,
                      seed: int = POSE_SEED) -> list[Trajectory]:
    """`per_kind` trajectories of each kind at each rate, from scene `name`'s content poses (the
    first per_kind * len(kinds) of draw_poses's even indices), seeded by `seed`."""
    if per_kind < 1 or seconds <= 0:
        raise ValueError(f"trajectories need at least one a kind and a positive duration, got {per_kind}, {seconds}")
    count = per_kind * len(kinds)
    anchors = [p for p in draw_poses(scene, name, 2 * count, seed) if p.kind == "content"][:count]
    bounds = pose_bounds(scene, name)
    key = zlib.crc32(name.encode())
    out = []
    for rate in rates:
        for i, (kind, anchor) in enumerate(zip([k for k in kinds for _ in range(per_kind)], anchors)):
            rng = np.random.default_rng([seed, key, 2, i])  # the same draws at every rate
            out.append(trajectory(kind, anchor, rate, seconds, bounds, rng))
    return out


def from_path(path, rate_hz: float) -> Trajectory:
    """A recorded camera path (the preview's P, rayvr/frame/cameras/rig.py save_path) as a
    trajectory: its poses one a frame at `rate_hz`."""
    poses = load_path(path)
    return Trajectory("recorded", float(rate_hz), tuple(poses), tuple(k / float(rate_hz) for k in range(len(poses))))


def angular_speeds_deg_s(traj: Trajectory) -> np.ndarray:
    """The head's rotation between consecutive poses (the angle of R_k^T R_k+1), degrees a second."""
    r = np.stack([p.rotation for p in traj.poses])
    trace = np.einsum("kij,kij->k", r[:-1], r[1:])  # tr(R_k^T R_k+1)
    return np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))) * traj.rate_hz


def linear_speeds_m_s(traj: Trajectory) -> np.ndarray:
    """The head's horizontal travel between consecutive poses, metres a second."""
    p = np.stack([q.position for q in traj.poses])
    step = p[1:] - p[:-1]
    return np.hypot(step[:, 0], step[:, 2]) * traj.rate_hz
