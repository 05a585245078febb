"""Multi-view captures (light fields, training views for NeRF / 3D Gaussian splatting): where the
views come from and the camera files that describe them.

A view source is a JSON file (`--views FILE`) or a generated set around the scene
(`--views sphere:N`, `--views grid:NxM[:SPACING]`). A sphere's views look at its centre; in a
scene whose bounds hold the camera (a room, seen from inside) the sphere is shrunk into the
bounds, 10 % of each extent from the walls, floor and ceiling, and a view that stands in or behind
an object, or within 15 % of the radius of a surface, moves nearer the centre. A file holds a
list of views, or an object with "views" or "frames" (so a `transforms.json` can be replayed)
whose top-level intrinsics are the views' defaults. Each view has a pose, one of
    "transform_matrix": 4x4 camera-to-world, OpenGL axes (what transforms.json holds)
    "position" + "rotation" (3x3 camera-to-world), or "position" + "target" (+ "up")
and optional intrinsics at the capture's --size, one of
    "fov_y" (degrees), "camera_angle_x" (radians, horizontal, as NeRF), or
    "fl_x" (+ "fl_y", "cx", "cy", pixels; rows top-down, so cy is measured from the top).

Every image a multi-view capture writes is described in `transforms.json` in the layout NeRF's
Blender loader, instant-ngp, nerfstudio and 3D Gaussian splatting read: `camera_angle_x`,
`fl_x`/`fl_y`/`cx`/`cy`/`w`/`h`, and per frame `file_path` (no extension: those loaders append
`.png`), `depth_file_path` and a camera-to-world `transform_matrix` in OpenGL axes (+X right, +Y
up, looking down -Z). Stereo views give two frames each, one per eye, with the eye's own pose.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..frame.cameras.rig import Pose, StereoRig, _check_pose, check_camera_positions
from .capture_files import aux_file, file_name, flow_file
from .flow import DIRECTIONS, FLOW_AUX, STATIC_SCENE_NOTE, flow_directions
from ..frame.cameras.pinhole import MAX_TANGENT, MIN_PIXEL_TANGENT
from ..util.inputs import read_json
from ..gl.limits import MAX_CAMERA_COORDINATE, check_range
from ..util.output import atomic_write_bytes
from ..gl.gpu_layout import NO_HIT

POSE_KEYS = ("transform_matrix", "position", "rotation", "target", "up")
INTRINSIC_KEYS = ("fov_y", "camera_angle_x", "fl_x", "fl_y", "cx", "cy", "w", "h")
# What transforms.json files carry besides poses and intrinsics: read past, never used.
FLOW_KEYS = tuple(f"flow_{d}{m}_file_path" for d in DIRECTIONS for m in ("", "_valid"))  # --aux flow's files
PASSED_KEYS = ("file_path", "depth_file_path", "material_file_path", "distance_file_path", "camera_file_path", "mask_path", "colmap_im_id", "name",
               "camera_angle_y", *FLOW_KEYS)
MAX_VIEWS = 1_000_000
CONVENTION = ("OpenGL camera axes: +X right, +Y up, looking down -Z; camera_to_world maps camera to world "
              "coordinates; pixel rows top-down (cy from the top); depth files hold linear view depth "
              "along -Z, 0 = background")
# The depth of a model whose depth is the distance along each pixel's (unit) ray (the wide one:
# CameraModel.depth_along_ray), as nerfstudio reads the depth of its fisheye and equirectangular
# cameras, whose ray directions have length 1.
RAY_DEPTH_CONVENTION = CONVENTION.replace("linear view depth along -Z", "the distance along each pixel's ray")


def _number(where: str, key: str, value, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{where}: {key!r} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ValueError(f"{where}: {key!r} must be > 0, got {value!r}")
    return float(value)


def view_pose(d: dict, where: str) -> Pose:
    """A view's pose from transform_matrix, position+rotation or position+target(+up)."""
    try:
        if "transform_matrix" in d:
            m = np.asarray(d["transform_matrix"], dtype=np.float64)
            if m.shape != (4, 4):
                raise ValueError(f"transform_matrix must be 4x4, got shape {m.shape}")
            if not np.allclose(m[3], (0, 0, 0, 1)):
                raise ValueError(f"transform_matrix's last row must be 0 0 0 1, got {m[3].tolist()}")
            pose = Pose(m[:3, 3].copy(), m[:3, :3].copy())
        elif "position" in d and ("rotation" in d or "target" in d):
            pose = Pose.from_dict(d)
        else:
            raise ValueError("needs 'transform_matrix', 'position' + 'rotation' or 'position' + 'target'")
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    problem = _check_pose(pose)
    if problem:
        raise ValueError(f"{where}: {problem}")
    return pose


def view_intrinsics(d: dict, size, where: str) -> dict | None:
    """StereoRig fields a view's intrinsics set (fov_y, or per-eye tangents from focal lengths and
    principal point), or None for the rig's own."""
    w, h = size
    for key, want in (("w", w), ("h", h)):
        if key in d and _number(where, key, d[key], positive=True) != want:
            raise ValueError(f"{where}: the view is {d.get('w', w)}x{d.get('h', h)} pixels but the capture's "
                             f"--size is {w}x{h}; every view renders at --size")
    given = [k for k in ("fov_y", "camera_angle_x", "fl_x") if k in d]
    if "fov_y" in given and len(given) > 1:
        raise ValueError(f"{where}: give one of fov_y, camera_angle_x, fl_x, not {' and '.join(given)}")
    if len(given) > 1:  # transforms.json carries both; they must tell the same camera
        fx, cx = _number(where, "fl_x", d["fl_x"], positive=True), _number(where, "cx", d.get("cx", w / 2))
        ax = _number(where, "camera_angle_x", d["camera_angle_x"], positive=True)
        if not math.isclose(math.atan(cx / fx) + math.atan((w - cx) / fx), ax, rel_tol=1e-6):
            raise ValueError(f"{where}: camera_angle_x {ax:g} disagrees with fl_x {fx:g} and cx {cx:g} at width {w}")
        d = {k: v for k, v in d.items() if k != "camera_angle_x"}  # then fl_x says the rest (fl_y, cy)
    if "fov_y" in d:
        fov = _number(where, "fov_y", d["fov_y"], positive=True)
        if fov >= 180:
            raise ValueError(f"{where}: fov_y must be below 180 degrees, got {fov}")
        return {"fov_y": fov}
    if "camera_angle_x" in d:
        ax = _number(where, "camera_angle_x", d["camera_angle_x"], positive=True)
        if ax >= math.pi:
            raise ValueError(f"{where}: camera_angle_x must be below pi radians, got {ax}")
        return {"fov_y": math.degrees(2 * math.atan(math.tan(ax / 2) * h / w))}
    if "fl_x" in d:
        fx = _number(where, "fl_x", d["fl_x"], positive=True)
        fy = _number(where, "fl_y", d.get("fl_y", fx), positive=True)
        cx = _number(where, "cx", d.get("cx", w / 2))
        cy = _number(where, "cy", d.get("cy", h / 2))
        if not (0 < cx < w and 0 < cy < h):
            raise ValueError(f"{where}: principal point ({cx:g}, {cy:g}) lies outside the {w}x{h} image")
        # A pixel is 1 / fl of tangent and the image's edges reach (distance to cx or cy) / fl: both
        # within the pinhole's float32 precision (frame/cameras/pinhole.py).
        for key, f, reach in (("fl_x", fx, max(cx, w - cx)), ("fl_y", fy, max(cy, h - cy))):
            check_range(f"{where}: {key!r} (pixels)", f, reach / MAX_TANGENT, 1.0 / MIN_PIXEL_TANGENT)
        t = (-cx / fx, (w - cx) / fx, -(h - cy) / fy, cy / fy)
        return {"eye_tangents": {"left": t, "right": t}}
    for key in ("fl_y", "cx", "cy"):
        if key in d:
            raise ValueError(f"{where}: {key!r} needs 'fl_x'")
    return None


def load_views(path, size) -> tuple[list[Pose], list]:
    """(poses, per-view rig overrides) from a views file; errors name the file, the view and the key."""
    path = Path(path)
    data = read_json(path, "views file")
    defaults = {}
    if isinstance(data, dict):
        lists = [k for k in ("views", "frames") if k in data]
        if not lists:
            raise ValueError(f"{path}: a views file is a list of views or an object with 'views' or 'frames'")
        model = data.get("camera_model", "OPENCV")
        distortion = [k for k in DISTORTION_KEYS if data.get(k, 0.0) != 0.0]
        if model not in PINHOLE_MODELS or distortion:
            raise ValueError(f"{path}: camera_model {model!r}{' with ' + distortion[0] if distortion else ''}: a "
                             f"views file's intrinsics are a pinhole's (camera_model {', '.join(PINHOLE_MODELS)}, no "
                             f"distortion); give another camera with --camera-model")
        defaults = {k: v for k, v in data.items() if k in INTRINSIC_KEYS}
        data = data[lists[0]]
    if not isinstance(data, list) or not data:
        raise ValueError(f"{path}: the views must be a non-empty list")
    if len(data) > MAX_VIEWS:
        raise ValueError(f"{path}: {len(data)} views; at most {MAX_VIEWS}")
    poses, overrides = [], []
    for i, d in enumerate(data):
        where = f"{path}: view {i}"
        if not isinstance(d, dict):
            raise ValueError(f"{where}: must be an object, got {type(d).__name__}")
        unknown = [k for k in d if k not in POSE_KEYS + INTRINSIC_KEYS + PASSED_KEYS + DISTORTION_KEYS]
        distorted = [k for k in DISTORTION_KEYS if d.get(k, 0.0) != 0.0]
        if distorted:
            raise ValueError(f"{where}: {distorted[0]} {d[distorted[0]]!r}: a view's intrinsics are a pinhole's, "
                             f"without distortion")
        if unknown:
            raise ValueError(f"{where}: unknown key {unknown[0]!r}; a view has {', '.join(POSE_KEYS + INTRINSIC_KEYS)}")
        own = [k for k in ("fov_y", "camera_angle_x", "fl_x") if k in d]
        merged = {**({} if own else defaults), **d}  # a view's own intrinsics replace the file's defaults
        poses.append(view_pose(d, where))
        overrides.append(view_intrinsics(merged, size, where))
    return poses, overrides


def sphere_views(center, radius: float, n: int) -> list[Pose]:
    """n views on a sphere (Fibonacci lattice: even spacing, no two at a pole) looking at center."""
    center = np.asarray(center, np.float64)
    golden = math.pi * (3 - math.sqrt(5))
    out = []
    for i in range(n):
        y = 1 - (2 * i + 1) / n
        r = math.sqrt(max(1 - y * y, 0.0))
        d = np.array([r * math.cos(golden * i), y, r * math.sin(golden * i)])
        out.append(Pose.look_at(center + radius * d, center))
    return out


# An enclosed scene (its bounds hold the capture's camera: a room) keeps its views this share of
# each axis's extent away from the bounds' faces: off the floor, the ceiling and the walls.
ROOM_MARGIN = 0.1
# A view in a room keeps at least this share of the sphere's radius of free space along each axis.
ROOM_CLEARANCE = 0.15
# Radii a view that is not in free space tries instead, as shares of the sphere's radius, along
# its own direction from the centre.
ROOM_RETREATS = (0.75, 0.5, 0.25)
AXES = np.vstack([np.eye(3), -np.eye(3)])


def encloses(scene, position) -> bool:
    """The scene's bounds hold `position`: a room or a building seen from inside."""
    lo, hi = np.asarray(scene.bounds, np.float64)  # world coordinates, as the pose's
    p = np.asarray(position, np.float64)
    return bool(np.all(p > lo) and np.all(p < hi))


def room_sphere(scene, target, distance: float) -> tuple[np.ndarray, float]:
    """Centre and radius of a view sphere inside an enclosed scene's free box (its bounds shrunk
    by ROOM_MARGIN of each extent): the target moved into the box's middle half, the radius at most
    `distance` and small enough that the sphere stays inside the box."""
    lo, hi = np.asarray(scene.bounds, np.float64)
    margin = ROOM_MARGIN * (hi - lo)
    lo, hi = lo + margin, hi - margin
    # The centre keeps to the middle half of the box: a target by a wall still leaves a sphere.
    quarter = 0.25 * (hi - lo)
    center = np.clip(np.asarray(target, np.float64), lo + quarter, hi - quarter)
    return center, float(min(distance, *(center - lo), *(hi - center)))


def in_free_space(scene, bvh, positions, center, clearance: float) -> np.ndarray:
    """Per position: no surface nearer than `clearance` along any axis, and nothing between it
    and `center`, which it looks at (a view inside an object, or behind one, sees that object)."""
    from ..accel.bvh import trace_reference

    p = np.asarray(positions, np.float64) - scene.origin
    to_center = np.asarray(center, np.float64) - scene.origin - p
    reach = np.linalg.norm(to_center, axis=1)
    rays = len(AXES) + 1
    origins = np.repeat(p, rays, axis=0)
    directions = np.concatenate([np.broadcast_to(AXES, (len(p), *AXES.shape)),
                                 (to_center / np.maximum(reach, 1e-12)[:, None])[:, None]], axis=1).reshape(-1, 3)
    tmax = np.concatenate([np.full((len(p), len(AXES)), clearance), reach[:, None]], axis=1).ravel()
    blocked = trace_reference(bvh, origins, directions, tmax=tmax, any_hit=True)
    return ~blocked.reshape(len(p), rays).any(axis=1)


def room_views(scene, target, distance: float, n: int) -> list[Pose]:
    """sphere_views for an enclosed scene: the sphere inside its free box (room_sphere), each view
    that stands in or behind an object or against a surface (in_free_space) moved nearer the centre
    along its own direction; ValueError when one finds no free place."""
    from ..accel.scene import build_scene_bvh

    center, radius = room_sphere(scene, target, distance)
    poses = sphere_views(center, radius, n)
    bvh = build_scene_bvh(scene, progress=False)
    clearance = ROOM_CLEARANCE * radius
    free = in_free_space(scene, bvh, [q.position for q in poses], center, clearance)
    for share in ROOM_RETREATS:
        stuck = np.flatnonzero(~free)
        if not len(stuck):
            break
        moved = [center + share * (poses[i].position - center) for i in stuck]
        ok = in_free_space(scene, bvh, moved, center, clearance)
        for i, position, good in zip(stuck, moved, ok):
            if good:
                poses[i], free[i] = Pose.look_at(position, center), True
    if not free.all():
        i = int(np.flatnonzero(~free)[0])
        raise ValueError(f"--views sphere:{n}: view {i} finds no free space between the room's centre "
                         f"{np.round(center, 3).tolist()} and its place on the sphere (radius {radius:.3g})")
    return poses


def grid_views(pose: Pose, nx: int, ny: int, spacing: float) -> list[Pose]:
    """An nx x ny camera array (a light-field rig): parallel views on the plane through `pose`
    across its view direction, `spacing` apart, rows top to bottom, columns left to right."""
    right, up = pose.rotation[:, 0], pose.rotation[:, 1]
    out = []
    for j in range(ny):
        for i in range(nx):
            offset = (i - (nx - 1) / 2) * spacing * right - (j - (ny - 1) / 2) * spacing * up
            out.append(Pose(pose.position + offset, pose.rotation.copy()))
    return out


def _spec_counts(spec: str, kind: str, parts: int) -> list[int]:
    try:
        counts = [int(x) for x in spec.split("x")]
    except ValueError:
        counts = []
    if len(counts) != parts or min(counts) < 1 or math.prod(counts) > MAX_VIEWS:
        shape = "N" if parts == 1 else "NxM"
        raise ValueError(f"--views {kind}:{shape} needs {'a whole number' if parts == 1 else 'whole numbers'} "
                         f"from 1 (at most {MAX_VIEWS} views), got {spec!r}")
    return counts


def views_for(spec: str, scene, rig: StereoRig) -> tuple[list[Pose], list]:
    """(poses, rig overrides) of `--views SPEC`: sphere:N, grid:NxM[:SPACING] or a views file,
    each view checked before any rendering: its camera lies within the GPU's float32 range of the
    scene, its rig renders, and transforms.json can describe its camera model."""
    poses, overrides = _views(spec, scene, rig)
    where = f"--views {spec}"
    check_camera_positions(poses, scene.origin, f"{where}: view")
    checked = {}
    for i, extra in enumerate(overrides):
        key = repr(extra)
        if key in checked:
            continue
        try:
            view_rig = StereoRig(**{**rig.__dict__, "pose": poses[i], **(extra or {})})
            for eye in view_rig.eyes():
                camera_model_fields(eye)
        except ValueError as exc:
            raise ValueError(f"{where}: view {i}: {exc}") from None
        checked[key] = True
    return poses, overrides


def _views(spec: str, scene, rig: StereoRig) -> tuple[list[Pose], list]:
    kind, _, rest = spec.partition(":")
    target = scene.center if scene.camera is None else rig.pose.position + rig.pose.forward * 2.0
    distance = float(np.linalg.norm(rig.pose.position - target)) or 1.0
    if kind == "sphere" and rest:
        (n,) = _spec_counts(rest, "sphere", 1)
        if encloses(scene, rig.pose.position):  # a room: views inside it, not under its floor
            return room_views(scene, target, distance, n), [None] * n
        return sphere_views(target, distance, n), [None] * n
    if kind == "grid" and rest:
        counts, _, spacing = rest.partition(":")
        nx, ny = _spec_counts(counts, "grid", 2)
        step = 0.05 * distance  # default: the array spans a few degrees of the scene
        if spacing:
            try:
                step = float(spacing)
            except ValueError:
                step = -1.0
            widest = MAX_CAMERA_COORDINATE / max(nx, ny)  # the array's span stays within the GPU's float32 range
            if not (math.isfinite(step) and 0 < step <= widest):
                raise ValueError(f"--views grid:NxM:SPACING needs a positive spacing, at most {widest:.3g} for "
                                 f"{nx}x{ny} views, got {spacing!r}")
        return grid_views(rig.pose, nx, ny, step), [None] * (nx * ny)
    return load_views(spec, rig.size)


PINHOLE_MODELS = ("OPENCV", "PINHOLE", "SIMPLE_PINHOLE")  # camera_model values of an undistorted pinhole
DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "p1", "p2")


def camera_model_fields(eye) -> dict:
    """The camera model of one eye image as nerfstudio's transforms.json spells it: its model's
    transforms_fields (rayvr/frame/cameras/base.py); ValueError where none of nerfstudio's models is it."""
    return eye.camera.transforms_fields(eye)


def camera_record(eye) -> dict:
    """One eye image's camera (an EyeView): its camera model (camera_model_fields) and camera-to-world."""
    c2w = np.eye(4)
    c2w[:3, :3], c2w[:3, 3] = eye.rotation, eye.position
    return {"w": eye.size[0], "h": eye.size[1], **camera_model_fields(eye), "near": eye.near, "far": eye.far,
            "camera_to_world": c2w.tolist(),
            "convention": RAY_DEPTH_CONVENTION if eye.camera.depth_along_ray else CONVENTION}


def camera_json(eye) -> bytes:
    """camera_record as JSON, refused (ValueError) if a value would be NaN or infinite, which JSON lacks."""
    return json.dumps(camera_record(eye), indent=1, allow_nan=False).encode()


def transforms(job, material_names=None) -> dict:
    """transforms.json for a capture job (rayvr.app.capture.CaptureJob): one frame per eye image.
    With the `material` aux, each frame names its material-ID image (`material_file_path`) and
    the top its IDs' material names (`materials`, from `material_names`: the scene's), so a mask
    of material k is `ids == k`."""
    frames = []
    for i in range(len(job.poses)):
        rig = job.frame_rig(i)
        for eye in job.eye_names:
            cam = camera_record(rig.eye(eye))
            image = file_name(job, i, eye, "color" if job.view == "color" else job.view, "png")
            frame = {"file_path": f"./{image.stem}", "transform_matrix": cam["camera_to_world"],
                     **{k: v for k, v in cam.items() if k not in RECORD_ONLY}}
            if "depth" in job.aux:
                frame["depth_file_path"] = f"./{aux_file(job, i, eye, 'depth').name}"
            if "material" in job.aux:
                frame["material_file_path"] = f"./{aux_file(job, i, eye, 'material').name}"
            if "distance" in job.aux:  # the other depth convention: the distance along each pixel's ray
                frame["distance_file_path"] = f"./{aux_file(job, i, eye, 'distance').name}"
            if FLOW_AUX in job.aux:  # null: no flow that way (the first frame's backward, the last's forward)
                has = flow_directions(job, i)
                for d in DIRECTIONS:
                    frame[f"flow_{d}_file_path"] = f"./{flow_file(job, i, eye, d).name}" if d in has else None
                    frame[f"flow_{d}_valid_file_path"] = \
                        f"./{flow_file(job, i, eye, d, mask=True).name}" if d in has else None
            frames.append(frame)
    # each frame's own files (file_path, depth_file_path, the flow's, ...) and pose never go to the top
    own = [k for k in frames[0] if k != "transform_matrix" and not k.endswith("file_path")]
    # A value every frame shares goes to the top only, the others stay in each frame: nerfstudio
    # takes a top-level intrinsic for every frame, and camera_model from the top alone.
    top = {k: frames[0][k] for k in own if all(f[k] == frames[0][k] for f in frames)}
    if "camera_model" not in top:
        raise ValueError("transforms.json: the frames' camera models differ; nerfstudio reads one for all")
    for f in frames:
        for k in top:
            del f[k]
    if FLOW_AUX in job.aux:
        top["flow"] = FLOW_NOTE
    if "material" in job.aux and material_names is not None:
        top["materials"] = {"background": int(NO_HIT), **{str(k): name for k, name in enumerate(material_names)}}
    return {**top, "frames": frames}


FLOW_NOTE = ("optical flow in pixels (dx right, dy down; pixel (x, y) shows what pixel (x + dx, y + dy) of the "
             "other frame shows), forward to the next frame's same eye, backward to the previous; NaN where "
             "invalid (no surface, outside the other image or occluded there), *_valid_file_path the bool mask; "
             "null: no such frame; " + STATIC_SCENE_NOTE)

RECORD_ONLY = ("camera_to_world", "near", "far")  # camera_record's keys transforms.json leaves out


def write_transforms(job, material_names=None) -> Path:
    p = job.out_dir / "transforms.json"
    atomic_write_bytes(p, json.dumps(transforms(job, material_names), indent=1, allow_nan=False).encode())
    return p
