"""`rayvr bench lights` (rayvr/bench/lights.py) at a tiny size: its rows, and what they must show
whatever the device: drawing more lights per surface leaves less noise, and every light (K = 0)
leaves only the area lights' noise, far below one pick's."""
from __future__ import annotations

import json

from rayvr.bench import lights


def test_bench_lights_rows_show_noise_falling_with_the_picks(tmp_path):
    result = lights.run(tmp_path, size=(24, 16), scenes=("default",), poses=1, repeat=1, frames=2,
                        reference_frames=2, picks=(0, 1, 8), progress=False)
    rows = result["rows"]
    assert [(r["pose"], r["light_picks"]) for r in rows] == [(p, k) for p in ("bench view", "head 0") for k in (0, 1, 8)]
    for pose in ("bench view", "head 0"):
        mse = {r["light_picks"]: r["mse"] for r in rows if r["pose"] == pose}
        assert mse[0] < 0.01 * mse[1] and mse[8] < mse[1], mse
    assert all(r["lights"] == r["scene_lights"] + lights.ADDED_LIGHTS for r in rows)
    saved = json.loads((tmp_path / "lights.json").read_text())
    assert saved["meta"]["bench"] == "lights" and len(saved["rows"]) == len(rows)
