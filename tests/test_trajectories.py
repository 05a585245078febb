"""Head trajectories (rayvr/bench/trajectories.py): each kind moves as its constants say, measured
on the poses themselves (rotation angles between frames, the head's travel), stays inside the
scene's region and level, is the same motion at 90 and 120 Hz, and a recorded path is one too."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rayvr.bench import trajectories as T
from rayvr.bench.head_poses import MIN_TARGET_M, pose_bounds
from rayvr.frame.cameras.rig import Pose, save_path
from rayvr.scene.loader import load


@pytest.fixture(scope="module")
def room():
    return load(None)


@pytest.fixture(scope="module")
def drawn(room):
    return {(t.kind, t.rate_hz): t for t in T.draw_trajectories(room, "default")}


def test_every_kind_at_both_rates_one_pose_a_frame(drawn):
    assert set(drawn) == {(k, float(r)) for k in T.KINDS for r in T.RATES_HZ}
    for (kind, rate), t in drawn.items():
        assert len(t.poses) == round(T.SECONDS * rate) + 1
        np.testing.assert_allclose(np.diff(t.times), 1.0 / rate)
        assert t.anchor.kind == "content"
        assert np.allclose(t.poses[0].position, t.anchor.position) and np.allclose(t.poses[0].rotation,
                                                                                    t.anchor.pose.rotation)


def test_turns_run_at_their_speeds(drawn):
    for rate in T.RATES_HZ:
        slow = T.angular_speeds_deg_s(drawn["slow_look", rate])
        held = slow[int(T.EASE_S * rate) + 1: -int(T.EASE_S * rate) - 1]
        np.testing.assert_allclose(held, T.SLOW_LOOK_DEG_S, rtol=1e-3)  # the hold, between the eases
        assert slow[0] < 0.2 * T.SLOW_LOOK_DEG_S and slow[-1] < 0.2 * T.SLOW_LOOK_DEG_S  # eased in and out
        fast = drawn["fast_turn", rate]
        speeds = T.angular_speeds_deg_s(fast)
        assert 0.97 * T.FAST_TURN_PEAK_DEG_S < speeds.max() <= T.FAST_TURN_PEAK_DEG_S * 1.001
        assert math.isclose(speeds.sum() / rate, T.FAST_TURN_DEG, rel_tol=1e-3)  # the whole turn, then a hold
        assert speeds[-5:].max() < 1e-6


def test_a_glance_goes_aside_and_comes_back(drawn):
    g = drawn["glance", 90.0]
    axes = np.stack([-p.rotation[:, 2] for p in g.poses])
    away = np.degrees(np.arccos(np.clip(axes @ axes[0], -1, 1)))
    start_cos = math.cos(math.radians(g.anchor.pitch_deg))  # a yaw of GLANCE_DEG moves the axis less off level
    expect = math.degrees(math.acos(1 - (1 - math.cos(math.radians(T.GLANCE_DEG))) * start_cos ** 2))
    assert math.isclose(away.max(), expect, rel_tol=1e-3)
    assert away[-1] < 1e-4  # back where it started
    assert T.angular_speeds_deg_s(g).max() == pytest.approx(15 / 8 * T.GLANCE_DEG / T.GLANCE_S, rel=0.01)


def test_a_walk_keeps_its_speed_its_gaze_and_the_room(room, drawn):
    bounds = pose_bounds(room, "default")
    for rate in T.RATES_HZ:
        w = drawn["walk", rate]
        speeds = T.linear_speeds_m_s(w)
        held = speeds[int(T.EASE_S * rate) + 1: -int(T.EASE_S * rate) - 1]
        np.testing.assert_allclose(held, T.WALK_M_S, rtol=1e-3)
        target = np.asarray(w.anchor.target)
        heights = []
        for p in w.poses:
            to_target = (target - p.position) / np.linalg.norm(target - p.position)
            assert np.dot(-p.rotation[:, 2], to_target) > math.cos(math.radians(0.01))  # gaze on the target
            assert abs(p.rotation[1, 0]) < 1e-9  # level: the eyes' axis stays horizontal
            assert bounds["x"][0] <= p.position[0] <= bounds["x"][1]
            assert bounds["z"][0] <= p.position[2] <= bounds["z"][1]
            assert np.linalg.norm(target - p.position) >= MIN_TARGET_M - 1e-9
            heights.append(p.position[1])
        bob = np.asarray(heights) - w.anchor.position[1]
        assert T.BOB_M * 0.9 < np.abs(bob).max() <= T.BOB_M + 1e-12


def test_the_same_motion_at_both_rates_and_seeded(room, drawn):
    for kind in T.KINDS:
        a, b = drawn[kind, 90.0], drawn[kind, 120.0]
        for t90, t120 in ((45, 60), (90, 120), (135, 180)):  # t = 0.5, 1.0, 1.5 s
            np.testing.assert_allclose(a.poses[t90].position, b.poses[t120].position, atol=1e-12)
            np.testing.assert_allclose(a.poses[t90].rotation, b.poses[t120].rotation, atol=1e-12)
    again = {(t.kind, t.rate_hz): t for t in T.draw_trajectories(room, "default", rates=(90,))}
    other = {(t.kind, t.rate_hz): t for t in T.draw_trajectories(room, "default", rates=(90,), seed=7)}
    for kind in T.KINDS:
        assert again[kind, 90.0].poses[-1].position.tolist() == drawn[kind, 90.0].poses[-1].position.tolist()
        assert again[kind, 90.0].poses[-1].rotation.tolist() == drawn[kind, 90.0].poses[-1].rotation.tolist()
    assert not np.allclose(other["walk", 90.0].poses[-1].position, again["walk", 90.0].poses[-1].position)


def test_a_recorded_path_is_a_trajectory(tmp_path):
    poses = [Pose.look_at([0.1 * k, 1.6, 2.0], [0.0, 1.0, 0.0]) for k in range(10)]
    save_path(tmp_path / "p.json", poses)
    t = T.from_path(tmp_path / "p.json", 90)
    assert t.kind == "recorded" and len(t.poses) == 10 and t.times[-1] == pytest.approx(9 / 90)
    np.testing.assert_allclose(T.linear_speeds_m_s(t), 0.1 * 90, rtol=1e-6)


def test_bad_arguments_are_one_line(room):
    with pytest.raises(ValueError, match="unknown trajectory kind 'jog'"):
        T.draw_trajectories(room, "default", kinds=("jog",))
    with pytest.raises(ValueError, match="positive duration"):
        T.draw_trajectories(room, "default", seconds=0)
