"""--aux flow (rayvr/app/flow.py): per-view optical flow of a capture's sequences, checked against
references that do not go through rayvr's projection (analytic translation, a rotation's
homography, ray-cast occlusion), end to end by warping one frame's colour onto the next, and the
refusal of a camera without a planar projection."""
import json
import math
import os

import numpy as np
import pytest
from PIL import Image

from conftest import run_rayvr
from rayvr.app.flow import optical_flow
from rayvr.frame.cameras.rig import EyeView

W, H = 64, 48
TAN = math.tan(math.radians(60) / 2)  # vertical half-angle tangent
TANGENTS = (-TAN * W / H, TAN * W / H, -TAN, TAN)
F = H / (2 * TAN)  # focal length in pixels (square pixels)


def eye(position, rotation=np.eye(3)):
    return EyeView("left", np.asarray(position, float), np.asarray(rotation, float), TANGENTS, 0.01, None, (W, H))


def pixel_rays(position, rotation):
    """World directions (camera-space -Z component 1, so t along one is the view depth) through the pixel
    centres, rows top-down, from the intrinsics alone."""
    xs, ys = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    cam = np.stack([(xs - W / 2) / F, -(ys - H / 2) / F, -np.ones_like(xs)], axis=-1)
    return cam @ np.asarray(rotation, float).T


def cast(position, rotation, planes=(), boxes=()):
    """(world positions, view depth along -Z) of the nearest of planes z = c (world) and
    axis-aligned boxes (lo, hi) through each pixel centre; depth 0 where nothing is hit."""
    d = pixel_rays(position, rotation)  # t along d is the view depth
    o = np.asarray(position, float)
    best = np.full((H, W), np.inf)
    for c in planes:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (c - o[2]) / d[..., 2]
        best = np.where((t > 0) & (t < best), t, best)
    for lo, hi in boxes:
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (np.asarray(lo) - o) / d, (np.asarray(hi) - o) / d
        near, far = np.minimum(t0, t1).max(axis=-1), np.maximum(t0, t1).min(axis=-1)
        best = np.where((near <= far) & (near > 0) & (near < best), near, best)
    hit = np.isfinite(best)
    t = np.where(hit, best, 0.0)
    return o + d * t[..., None], t


def test_sideways_translation_in_front_of_a_plane_is_f_t_over_z():
    z, t = 4.0, 0.25
    a, b = eye((0, 0, 0)), eye((t, 0, 0))
    position, depth = cast(a.position, a.rotation, planes=[-z])
    _, depth_b = cast(b.position, b.rotation, planes=[-z])
    assert np.allclose(depth, z)
    flow, valid = optical_flow(position, a, b, depth_b, hit=depth > 0)
    expected = -F * t / z  # the camera moves right: the plane moves left in the image
    xs = np.arange(W) + 0.5
    inside = np.broadcast_to(xs + expected >= 0, (H, W))
    assert (valid == inside).all()
    assert np.allclose(flow[valid, 0], expected, atol=1e-4) and np.allclose(flow[valid, 1], 0, atol=1e-4)
    assert np.isnan(flow[~valid]).all()
    # and back: the same amount the other way, invalid where it leaves the image on the right
    back, back_valid = optical_flow(cast(b.position, b.rotation, planes=[-z])[0], b, a, depth, hit=depth_b > 0)
    assert np.allclose(back[back_valid, 0], -expected, atol=1e-4)
    assert (back_valid == np.broadcast_to(xs - expected < W, (H, W))).all()


def test_rotation_about_the_vertical_axis_is_its_homography():
    angle = math.radians(5)
    r0 = np.eye(3)
    r1 = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0], [-math.sin(angle), 0, math.cos(angle)]])
    a, b = eye((0, 0, 0), r0), eye((0, 0, 0), r1)
    planes = [-6.0]
    position, depth = cast(a.position, r0, planes=planes)
    _, depth_b = cast(b.position, r1, planes=planes)
    flow, valid = optical_flow(position, a, b, depth_b, hit=depth > 0)
    # OpenCV camera axes (x right, y down, z forward) from rayvr's (y up, looking down -Z)
    k = np.array([[F, 0, W / 2], [0, F, H / 2], [0, 0, 1]])
    flip = np.diag([1.0, -1.0, -1.0])
    homography = k @ flip @ r1.T @ r0 @ flip @ np.linalg.inv(k)
    xs, ys = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    q = np.stack([xs, ys, np.ones_like(xs)], axis=-1) @ homography.T
    expected = q[..., :2] / q[..., 2:] - np.stack([xs, ys], axis=-1)
    inside = (xs + expected[..., 0] >= 0) & (xs + expected[..., 0] < W) & (ys + expected[..., 1] >= 0) & \
        (ys + expected[..., 1] < H)
    assert (valid == inside).all() and valid.mean() > 0.8
    assert np.abs(flow[valid] - expected[valid]).max() < 1e-3
    assert np.abs(expected[valid, 0]).min() > 1  # it does move: a turn to the left moves the image right
    assert (expected[valid, 0] > 0).all()


def test_wall_pixels_the_box_covers_in_the_next_frame_are_invalid():
    wall, box = [-8.0], [((-0.6, -0.6, -4.6), (0.6, 0.6, -3.4))]
    a, b = eye((0, 0, 0)), eye((0.8, 0, 0))
    position, depth = cast(a.position, a.rotation, planes=wall, boxes=box)
    _, depth_b = cast(b.position, b.rotation, planes=wall, boxes=box)
    flow, valid = optical_flow(position, a, b, depth_b, hit=depth > 0)
    on_wall = np.isclose(depth, 8.0)
    # independently: does the segment from eye b to the wall point pass through the box?
    o = b.position
    d = position - o
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (np.asarray(box[0][0]) - o) / d, (np.asarray(box[0][1]) - o) / d
    near, far = np.minimum(t0, t1).max(axis=-1), np.maximum(t0, t1).min(axis=-1)
    behind_box = on_wall & (near <= far) & (near > 0) & (near < 1)
    xs = np.arange(W) + 0.5
    target_x = xs[None, :] + np.where(valid, flow[..., 0], 0.0)
    assert behind_box.sum() > 50
    assert not (valid & behind_box).any()
    # and the wall pixels that stay in view and in the clear are valid, away from the box's outline
    lands = on_wall & ~behind_box
    q = b.project(position.reshape(-1, 3))[:, :2].reshape(H, W, 2)
    lands &= (q[..., 0] >= 1) & (q[..., 0] < W - 1)
    margin = np.zeros_like(lands)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            margin |= np.roll(np.roll(behind_box, dy, 0), dx, 1)
    assert (valid[lands & ~margin]).all() and (lands & ~margin).sum() > 500
    assert np.isfinite(target_x).all()
    # the box's own front face moves more than the wall (nearer)
    front = np.isclose(depth, 3.4) & valid
    assert front.any() and np.nanmean(flow[front, 0]) < np.nanmean(flow[valid & on_wall, 0])


def remap(image, map_x, map_y):
    """cv2.remap(image, map_x, map_y, INTER_LINEAR, BORDER_CONSTANT 0) in numpy: dst(y, x) =
    src(map_y, map_x), integer coordinates at pixel centres, bilinear between the four."""
    h, w = image.shape[:2]
    x0, y0 = np.floor(map_x).astype(int), np.floor(map_y).astype(int)
    fx, fy = (map_x - x0)[..., None], (map_y - y0)[..., None]
    out = np.zeros(map_x.shape + image.shape[2:])
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            xx, yy = x0 + dx, y0 + dy
            inside = ((xx >= 0) & (xx < w) & (yy >= 0) & (yy < h))[..., None]
            out += np.where(inside, image[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)], 0.0) * wx * wy
    return out


def test_capture_writes_flow_that_warps_one_frame_onto_the_next(tmp_path):
    run = run_rayvr("capture", "--frames", "3", "--aux", "flow", "--size", "96x72", "--eye", "left",
                    "--out", tmp_path, "-q")
    assert run.returncode == 0, run.stderr
    files = set(os.listdir(tmp_path))
    for i, directions in ((0, ["forward"]), (1, ["forward", "backward"]), (2, ["backward"])):
        for d in ("forward", "backward"):
            for name in (f"frame_{i:04d}_left_flow_{d}.npy", f"frame_{i:04d}_left_flow_{d}_valid.npy"):
                assert (name in files) == (d in directions), name
    assert not any("position" in f for f in files)  # read back for the flow, not written
    frames = json.loads((tmp_path / "transforms.json").read_text())["frames"]
    assert [f["flow_backward_file_path"] for f in frames] == [None, "./frame_0001_left_flow_backward.npy",
                                                             "./frame_0002_left_flow_backward.npy"]
    assert frames[2]["flow_forward_file_path"] is None
    assert frames[0]["flow_forward_valid_file_path"] == "./frame_0000_left_flow_forward_valid.npy"
    color = [np.asarray(Image.open(tmp_path / f"frame_{i:04d}_left.png"), np.float64) / 255 for i in range(3)]
    ys, xs = np.mgrid[0:72, 0:96].astype(np.float64)
    checked = 0
    for i, j, d in ((0, 1, "forward"), (1, 0, "backward"), (1, 2, "forward"), (2, 1, "backward")):
        flow = np.load(tmp_path / frames[i][f"flow_{d}_file_path"])
        valid = np.load(tmp_path / frames[i][f"flow_{d}_valid_file_path"])
        assert flow.shape == (72, 96, 2) and valid.dtype == bool
        assert np.isnan(flow[~valid]).all() and np.isfinite(flow[valid]).all()
        # frame j sampled where frame i's pixels went shows frame i (pixel centres: remap's integers)
        warped = remap(color[j], xs + np.nan_to_num(flow[..., 0]), ys + np.nan_to_num(flow[..., 1]))
        error = np.abs(warped - color[i]).max(axis=-1)[valid]
        assert valid.sum() > 200
        assert (error < 0.08).mean() > 0.85, (i, d, np.percentile(error, [50, 85, 95]))
        # and the flow is no identity: not warping matches less well
        still = np.abs(color[j] - color[i]).max(axis=-1)[valid]
        assert np.mean(still) > 2 * np.mean(error)
        checked += 1
    assert checked == 4


def test_flow_with_a_distorted_camera_is_one_line(tmp_path):
    run = run_rayvr("capture", "--frames", "2", "--aux", "flow", "--camera-model", "distorted", "--size", "16x12",
                    "--out", tmp_path / "o", "-q")
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "flow" in run.stderr and "'distorted'" in run.stderr, run.stderr
    assert not (tmp_path / "o").exists()
