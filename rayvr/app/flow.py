"""Optical flow of a capture's sequences (the `flow` aux of `rayvr capture`), on the CPU.

For each frame and eye, the forward flow (to the next frame's same eye) and the backward flow (to
the previous frame's) in pixels: (dx, dy) with x right and y down, the image's own rows top-down,
so pixel (x, y) of this frame shows what pixel (x + dx, y + dy) of the other frame shows (the
convention OpenCV's remap and most flow datasets use). The flow comes from geometry, not from the
images: each pixel's world position (the `position` aux, the surface its centre's ray hit) is
projected through the other frame's eye (EyeView.project, the planar frustum the rasterizer
draws). A pixel is invalid (NaN in the flow, False in the mask) where it hit no surface, where its
point lies behind the other eye or outside its image, or where the other frame sees something
else there: its view depth differs by more than `tolerance` of the depth from the other frame's
own depth where it lands, interpolated bilinearly between the four pixels around that place
(occluded; interpolated, not the nearest pixel's, so a surface seen at a grazing angle is not
called occluded by its own depth's slope across a pixel, and a point beside an occluder's outline,
where the four mix two surfaces, is not trusted either).

A static scene only: the flow is the camera's motion through a scene that stays where it is;
moving meshes (a scene's animation) are not flowed. Planar (pinhole) cameras only: a model
without a planar frustum has no EyeView.project to flow through (check_flow_camera).
"""
from __future__ import annotations

import numpy as np

FLOW_AUX = "flow"  # the capture's aux name; not a read-back channel: made from "position" and the depth
DIRECTIONS = ("forward", "backward")  # to the next frame, to the previous one
DEPTH_TOLERANCE = 0.01  # relative: a point is visible in the other frame when its depth agrees this well
STATIC_SCENE_NOTE = "flow assumes a static scene: the camera moves, moving meshes are not flowed"


def check_flow_camera(camera) -> None:
    """ValueError in one line unless `camera` (a camera model) has a planar frustum to flow through."""
    if not getattr(camera, "rasterizable", False):
        raise ValueError(f"--aux flow needs a planar (pinhole) camera: the {camera.name!r} camera model has no "
                         f"planar projection to compute flow through; use --camera-model pinhole or leave out flow")


def optical_flow(position, eye_from, eye_to, depth_to, hit=None, tolerance: float = DEPTH_TOLERANCE):
    """(flow, valid) of one eye image: `position` (H, W, 3) world positions of the pixels of
    `eye_from` (an EyeView), `eye_to` the other frame's eye and `depth_to` (H', W') its linear view
    depth (0: background). `hit` (H, W) marks the pixels that saw a surface (default: those whose
    position is finite). flow is (H, W, 2) float32 pixels (dx right, dy down), NaN where not valid;
    valid (H, W) bool."""
    p = np.asarray(position, np.float64)
    h, w = p.shape[:2]
    hit = np.isfinite(p).all(axis=-1) if hit is None else np.asarray(hit, bool) & np.isfinite(p).all(axis=-1)
    pts = np.where(hit[..., None], p, 0.0).reshape(-1, 3)
    # view depth in the other eye (along its -Z)
    z = -((pts - np.asarray(eye_to.position, np.float64)) @ np.asarray(eye_to.rotation, np.float64))[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        q = eye_to.project(pts)[:, :2]
    tw, th = eye_to.size
    depth_to = np.asarray(depth_to, np.float64)
    if depth_to.shape != (th, tw):
        raise ValueError(f"depth_to is {depth_to.shape}, the other eye's image is {th}x{tw}")
    ok = hit.ravel() & (z > 0) & np.isfinite(q).all(axis=1)
    qx, qy = np.where(ok, q[:, 0], -1.0), np.where(ok, q[:, 1], -1.0)
    ok &= (qx >= 0) & (qx < tw) & (qy >= 0) & (qy < th)
    # the other frame's depth where each point lands: bilinear between the four pixels (centres at
    # +.5) around it, clamped into the image; one of them background or another surface (a depth
    # step: a silhouette) spoils the mix, so a point next to an occluder's outline is not trusted
    fx, fy = np.clip(qx - 0.5, 0, tw - 1), np.clip(qy - 0.5, 0, th - 1)
    x0, y0 = np.minimum(fx.astype(np.int64), max(tw - 2, 0)), np.minimum(fy.astype(np.int64), max(th - 2, 0))
    x1, y1 = np.minimum(x0 + 1, tw - 1), np.minimum(y0 + 1, th - 1)
    ax, ay = fx - x0, fy - y0
    seen = np.ones(len(pts), bool)
    mixed = np.zeros(len(pts))
    for yy, xx, weight in ((y0, x0, (1 - ax) * (1 - ay)), (y0, x1, ax * (1 - ay)), (y1, x0, (1 - ax) * ay),
                           (y1, x1, ax * ay)):
        d = depth_to[yy, xx]
        seen &= (d > 0) | (weight == 0)
        mixed += weight * d
    ok &= seen & (np.abs(mixed - z) <= tolerance * np.abs(z))
    xs, ys = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    flow = np.stack([q[:, 0].reshape(h, w) - xs, q[:, 1].reshape(h, w) - ys], axis=-1)
    valid = ok.reshape(h, w)
    return np.where(valid[..., None], flow, np.nan).astype(np.float32), valid


def frame_flows(job, index: int, frame, neighbours: dict) -> dict:
    """{(eye, direction): (flow, valid)} of frame `index` of a capture job: `neighbours` maps
    "forward" / "backward" to the next / previous frame (a Frame), left out where there is none."""
    out = {}
    rig = job.frame_rig(index)
    for eye, img in frame.eyes.items():
        position, depth = img.aux["position"], img.depth
        for direction, other in neighbours.items():
            j = index + 1 if direction == "forward" else index - 1
            out[eye, direction] = optical_flow(position, rig.eye(eye), job.frame_rig(j).eye(eye),
                                               other.eyes[eye].depth, hit=depth > 0)
    return out


def flow_directions(job, index: int) -> tuple:
    """The flows frame `index` of `job` has: no backward flow for the first frame, no forward for the last."""
    if FLOW_AUX not in job.aux:
        return ()
    n = len(job.poses)
    return tuple(d for d in DIRECTIONS if (index + 1 < n if d == "forward" else index > 0))


def render_order(job, indices) -> list[int]:
    """The frames to render to write `indices`: with flow also their neighbours (not written)."""
    if FLOW_AUX not in job.aux:
        return list(indices)
    n = len(job.poses)
    return sorted({k for i in indices for k in (i - 1, i, i + 1) if 0 <= k < n})
