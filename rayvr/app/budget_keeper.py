"""The preview's budget mode over time: a pick made for one view is stale once the head has gone
somewhere else (other materials cover the screen, another mirror is in sight), so the preview
picks again when the view has changed enough and then settled, not while it is moving (a pick
measures a few dozen frames from one still view). K picks again at once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

REPICK_MOVE = 0.15  # of the scene's extent: a head moved this far sees another scene
REPICK_TURN_DEG = 30.0  # a head turned this far looks at other materials
SETTLE_S = 0.75  # still this long (no move or turn beyond the settle tolerances) before a pick
SETTLE_MOVE = 0.002  # of the scene's extent per check: below this the view counts as still
SETTLE_TURN_DEG = 0.5


def _turn_deg(r0: np.ndarray, r1: np.ndarray) -> float:
    """The angle between two camera-to-world rotations, in degrees."""
    c = (np.trace(np.asarray(r0, float).T @ np.asarray(r1, float)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


@dataclass
class BudgetKeeper:
    budget_ms: float
    extent: float  # the scene's size: the distances scale with it
    picked_at: tuple | None = None  # (position, rotation) of the last pick's view
    summary: dict | None = None  # the last pick (budget.describe_pick's input)
    _last: tuple | None = field(default=None, repr=False)  # the view at the previous check
    _still_since: float | None = field(default=None, repr=False)

    def picked(self, pose, summary: dict) -> None:
        self.picked_at = (np.array(pose.position, float), np.array(pose.rotation, float))
        self.summary = summary
        self._still_since = None

    def changed_since_pick(self, pose) -> bool:
        if self.picked_at is None:
            return True
        moved = float(np.linalg.norm(np.asarray(pose.position, float) - self.picked_at[0]))
        return moved > REPICK_MOVE * self.extent or _turn_deg(self.picked_at[1], pose.rotation) > REPICK_TURN_DEG

    def due(self, pose, now: float) -> bool:
        """True when the view has changed enough since the last pick and has been still for
        SETTLE_S: the moment to pick again. Call once a frame."""
        view = (np.array(pose.position, float), np.array(pose.rotation, float))
        last, self._last = self._last, view
        if last is not None:
            moving = (float(np.linalg.norm(view[0] - last[0])) > SETTLE_MOVE * self.extent
                      or _turn_deg(last[1], view[1]) > SETTLE_TURN_DEG)
            if moving:
                self._still_since = None
        if self._still_since is None:
            self._still_since = now
        return now - self._still_since >= SETTLE_S and self.changed_since_pick(pose)

    def hud_text(self) -> str:
        """One line: the budget, what the last pick measured, and what it chose."""
        s = self.summary
        head = f"budget {self.budget_ms:.4g} ms ({1000.0 / self.budget_ms:.0f} Hz)"
        if s is None:
            return f"{head}: picking ..."
        counts: dict = {}
        for effect in s["assignment"].values():
            counts[effect] = counts.get(effect, 0) + 1
        chosen = ", ".join(f"{e} {n}" for e, n in sorted(counts.items(), key=lambda kv: -kv[1]))
        state = "within" if s["within_budget"] else "OVER"
        return (f"{head}: {state}, measured {s['measured_ms']:.2f} ms, FLIP {s['measured_flip']:.3f}; "
                f"picked {chosen}; picks again when the view changes (K: now)")
