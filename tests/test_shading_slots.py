"""shading_slots (--shading-slots N): an MSAA pixel shades at most its N most covered distinct
triangles, and the frame runs at most N rounds. Against the frame that shades every triangle (8
slots): a pixel with at most N triangles is the same to the bit (the same entries, weights and order
of sums), one with more keeps weights that sum to one (no pixel darkens for the dropped ones), and
the frame's rounds are min(N, the most triangles a pixel saw)."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr import Renderer
from rayvr.frame.cameras import Distorted
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.options import OptionError
from rayvr.renderer import RenderSettings
from rayvr.scene.loader import load

ROOM_POSE = Pose.look_at([0.3, 1.5, 1.0], [0, 1.2, -1])  # inside the default room: edges everywhere


@pytest.fixture(scope="module")
def room():
    return load(None)


def frame(gl, room, rig, slots, **settings):
    with Renderer(room, gl=gl, settings=RenderSettings(shading_slots=slots, seed=5, **settings)) as r:
        fc = r.record(rig)
        r.gl.ctx.finish()
        rounds = len([k for k in r.read_round_ms(fc).get("sample_accumulate", [])])
        out = r.render(rig)
        n = r.plan(camera=rig.camera).subsamples
        hits = np.frombuffer(r.resource("msaa_hits").read(), np.uint32)
    lists = hits.reshape(-1, 2, rig.size[1], rig.size[0], 4)
    counts = (lists[0, ..., 2] >> 8) & 255  # the pixel's kept triangles (GL rows, bottom-up)
    color = np.stack([np.asarray(out.left.color), np.asarray(out.right.color)])[..., :3].astype(np.float64)
    return color, counts[:, ::-1], rounds, n


@pytest.mark.parametrize("camera", [None, Distorted()], ids=["pinhole", "distorted_chromatic"])
def test_fewer_slots_change_only_the_pixels_with_more_triangles(gl, room, camera):
    size = (40, 30)
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=size, near=1e-3,
                    **({"camera": camera} if camera is not None else {}))
    full, full_counts, full_rounds, _ = frame(gl, room, rig, 8, msaa=8, primary="rays")
    two, two_counts, two_rounds, _ = frame(gl, room, rig, 2, msaa=8, primary="rays")
    assert full_rounds >= 3 and full_counts.max() >= 3  # pixels of three and more triangles in view
    assert two_rounds == 2 and two_counts.max() == 2
    few = full_counts <= 2
    assert few.mean() > 0.5 and (~few).sum() >= 10
    np.testing.assert_array_equal(two[few], full[few])  # the same entries and sums, to the bit
    assert (two[~few] != full[~few]).any()  # the frame's resolved colour: the rounds' sums, not one round
    # where triangles were dropped the kept ones share the pixel: the same light, give or take what the
    # dropped ones saw (a dropped triangle covers little of its pixel), and never black
    many = ~few
    lum_full, lum_two = full[many].mean(-1), two[many].mean(-1)
    assert (lum_two > 0).all()
    assert abs(lum_two.mean() - lum_full.mean()) < 0.15 * lum_full.mean()


def test_shading_slots_is_bounded():
    with pytest.raises(OptionError, match="shading_slots"):
        RenderSettings(shading_slots=0)
    with pytest.raises(OptionError, match="shading_slots"):
        RenderSettings(shading_slots=9)
