"""The preview's budget mode over time (app/budget_keeper.py): it picks again only once the
view has changed enough since the last pick and has then held still."""
import numpy as np

from rayvr.app import budget_keeper as bk
from rayvr.frame.cameras.rig import Pose


def yaw(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def pose(x=0.0, turn=0.0):
    return Pose(np.array([x, 1.6, 0.0]), yaw(turn))


SUMMARY = {"within_budget": True, "measured_ms": 10.2, "measured_flip": 0.05,
           "assignment": {"a": "glossy", "b": "raster", "c": "raster"}}


def test_no_repick_while_the_view_stays_or_moves_a_little():
    k = bk.BudgetKeeper(11.1, extent=10.0)
    k.picked(pose(), SUMMARY)
    assert not any(k.due(pose(x=0.1 * i / 10, turn=i), 5.0 * i) for i in range(10))  # 0.1 m, 9 degrees


def test_repick_after_a_move_once_the_view_has_settled():
    k = bk.BudgetKeeper(11.1, extent=10.0)
    k.picked(pose(), SUMMARY)
    t = 0.0
    for i in range(20):  # walking 2 m (20 % of the extent) over 2 s: never while moving
        t += 0.1
        assert not k.due(pose(x=0.1 * (i + 1)), t)
    still = pose(x=2.0)
    assert not k.due(still, t + bk.SETTLE_S / 2)
    assert k.due(still, t + bk.SETTLE_S + 0.01)
    k.picked(still, SUMMARY)
    assert not k.due(still, t + 10.0)  # picked for this view: not again


def test_a_turn_alone_is_a_new_view():
    k = bk.BudgetKeeper(11.1, extent=10.0)
    k.picked(pose(), SUMMARY)
    assert not k.due(pose(turn=bk.REPICK_TURN_DEG + 5), 0.0)  # just turned: not settled yet
    assert k.due(pose(turn=bk.REPICK_TURN_DEG + 5), bk.SETTLE_S + 0.01)
    k.picked(pose(), SUMMARY)
    assert not k.due(pose(turn=bk.REPICK_TURN_DEG - 5), 100.0)


def test_hud_says_what_it_picked():
    k = bk.BudgetKeeper(1000 / 90, extent=10.0)
    assert "picking" in k.hud_text()
    k.picked(pose(), SUMMARY)
    text = k.hud_text()
    assert "11.11 ms (90 Hz)" in text and "within" in text and "raster 2, glossy 1" in text and "K" in text
    k.picked(pose(), {**SUMMARY, "within_budget": False})
    assert "OVER" in k.hud_text()
