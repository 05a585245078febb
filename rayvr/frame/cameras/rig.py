"""Cameras and the stereo rig.

Conventions (OpenGL): camera looks down -Z, +Y up, +X right; images are stored rows top-down.

Depth precision: rayvr uses **reversed-Z** with a [0, 1] clip range (`glClipControl(
GL_LOWER_LEFT, GL_ZERO_TO_ONE)`) into a 32-bit float depth buffer, and an **infinite far
plane** by default (`far=None`). Depth = near / view_distance, so the float's exponent tracks
distance and the relative depth resolution is nearly constant from `near` to infinity: two
surfaces 2e-6 x distance apart resolve without z-fighting for near/far from 1e-4 to 1e7 and
infinite far (tests/test_gbuffer.py; 5e-7 was seen to pass on llvmpipe, 2e-6 is what rayvr
advertises). Near/far ratios need no tuning. Without clip control the same projection is remapped to GL's
[-1, 1] range (works, with less precision far away; `rayvr info` says which is in use).

All matrices are built in float64 relative to the scene's origin (see scene/loader.py) and only then
cast to float32, so rigs 1e5 units from the world origin stay exact.

Rays come from the rig's camera model (rayvr/frame/cameras/, default the pinhole). The projection
matrices here describe the eye's planar frustum, which is what the rasterizer draws: exact for
the pinhole, the only rasterizable model.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import DEFAULT_CAMERA_MODEL, CameraModel, get_camera_model
from ...gl.limits import MAX_CAMERA_COORDINATE, MAX_DISTANCE, MIN_DISTANCE, check_range
from ...util.inputs import read_json
from ...util.output import atomic_write_bytes

EYES = ("left", "right")


def look_at_rotation(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Camera-to-world rotation (columns: right, up, back) looking from eye to target."""
    eye, target, up = (np.asarray(x, dtype=np.float64) for x in (eye, target, up))
    if not (np.isfinite(eye).all() and np.isfinite(target).all()):
        raise ValueError(f"camera eye {eye.tolist()} and target {target.tolist()} must be finite (no NaN or inf)")
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused next, not warned about
        back = eye - target
    if not np.isfinite(back).all():
        raise ValueError(f"camera eye {eye.tolist()} and target {target.tolist()} are too far apart for float64")
    if not back.any():
        raise ValueError("camera eye and target are the same point")
    back /= np.abs(back).max()  # first to ~1: the norm of 1e300-long vectors would overflow
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    if np.linalg.norm(right) < 1e-9:  # looking along `up`: pick another up
        right = np.cross([0.0, 0.0, 1.0] if abs(back[2]) < 0.9 else [1.0, 0.0, 0.0], back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    return np.stack([right, true_up, back], axis=1)


@dataclass
class Pose:
    """Head pose: world position (float64) and camera-to-world rotation (3x3)."""

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0)) -> "Pose":
        return cls(np.asarray(eye, dtype=np.float64), look_at_rotation(eye, target, up))

    @property
    def forward(self) -> np.ndarray:
        return -self.rotation[:, 2]

    def to_dict(self) -> dict:
        return {"position": self.position.tolist(), "rotation": self.rotation.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Pose":
        if "rotation" in d:
            return cls(np.asarray(d["position"], float), np.asarray(d["rotation"], float).reshape(3, 3))
        return cls.look_at(d["position"], d["target"], d.get("up", (0.0, 1.0, 0.0)))


def projection(left: float, right: float, bottom: float, top: float, near: float,
               far: float | None = None, zero_to_one: bool = True) -> np.ndarray:
    """Reversed-Z off-axis projection from frustum *tangents* (x/-z at the edges).

    Depth is near/d (d = view distance) for far=None; with a finite far it is 1 at near, 0 at far.
    `zero_to_one=False` remaps to GL's default [-1, 1] clip range (no clip control)."""
    if not (right > left and top > bottom):
        raise ValueError(f"empty frustum: tangents left={left} right={right} bottom={bottom} top={top}")
    if not near > 0:
        raise ValueError(f"near must be > 0, got {near}")
    p = np.zeros((4, 4))
    p[0, 0] = 2.0 / (right - left)
    p[0, 2] = (right + left) / (right - left)
    p[1, 1] = 2.0 / (top - bottom)
    p[1, 2] = (top + bottom) / (top - bottom)
    if far is None or math.isinf(far):
        p[2, 3] = near
    else:
        if not far > near:
            raise ValueError(f"far ({far}) must be greater than near ({near})")
        p[2, 2] = near / (far - near)
        p[2, 3] = near * far / (far - near)
    p[3, 2] = -1.0
    if not zero_to_one:
        p[2] = 2.0 * p[2] - p[3]
    return p


@dataclass
class EyeView:
    """One eye: where it is, how it projects (planar frustum) and its camera model, which makes
    its rays. `view` maps scene-local to eye space."""

    name: str
    position: np.ndarray  # world, float64
    rotation: np.ndarray  # camera-to-world
    tangents: tuple  # (left, right, bottom, top) frustum tangents
    near: float
    far: float | None
    size: tuple  # (width, height) in pixels
    camera: CameraModel = field(default_factory=lambda: get_camera_model(DEFAULT_CAMERA_MODEL))
    fov_y: float | None = None  # the rig's vertical field of view, degrees (non-planar models use it)

    def view_matrix(self, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
        """World-minus-`origin` -> eye space, float64."""
        m = np.eye(4)
        m[:3, :3] = self.rotation.T
        m[:3, 3] = -self.rotation.T @ (self.position - np.asarray(origin, dtype=np.float64))
        return m

    def projection_matrix(self, zero_to_one: bool = True) -> np.ndarray:
        return projection(*self.tangents, self.near, self.far, zero_to_one)

    def view_projection(self, origin=(0.0, 0.0, 0.0), zero_to_one: bool = True) -> np.ndarray:
        return self.projection_matrix(zero_to_one) @ self.view_matrix(origin)

    def project(self, points_world) -> np.ndarray:
        """World points -> (x, y) pixel coordinates (top-down rows, pixel centres at .5) and depth.
        Returns (N, 3): px, py, reversed-Z depth value."""
        p = np.atleast_2d(np.asarray(points_world, dtype=np.float64))
        clip = (self.view_projection() @ np.c_[p, np.ones(len(p))].T).T
        ndc = clip[:, :3] / clip[:, 3:4]
        w, h = self.size
        px = (ndc[:, 0] * 0.5 + 0.5) * w
        py = (1.0 - (ndc[:, 1] * 0.5 + 0.5)) * h
        return np.c_[px, py, ndc[:, 2]]

    def rays(self):
        """This eye's camera rays from its model (rayvr.frame.cameras.CameraRays: world origins, unit
        directions, footprints, validity; rows top-down)."""
        return self.camera.rays(self)

    def ray_directions(self) -> np.ndarray:
        """(H, W, 3) world-space unit directions through pixel centres (rows top-down). With the
        pinhole these come from the same tangents the rasterizer's projection uses, so rays and
        raster agree per pixel."""
        return self.camera.rays(self).directions


@dataclass
class StereoRig:
    """A head pose plus two eyes.

    Either symmetric per-eye frusta from `fov_y` (degrees) and the image aspect, sheared so the
    eyes' images coincide at `convergence` (None: parallel axes, as HMDs do), or HMD-style per-eye
    tangents `eye_tangents = {"left": (l, r, b, t), "right": (...)}` (tan of the half-angles, left
    and bottom negative) which take precedence. `ipd` is the distance between the eyes.
    `camera` is the camera model both eyes use (a rayvr.frame.cameras model or its registered name;
    default the pinhole); a model keeps any per-eye parameters itself, keyed by eye name.
    """

    pose: Pose = field(default_factory=Pose)
    ipd: float = 0.064
    fov_y: float = 90.0
    convergence: float | None = None
    near: float = 0.05
    far: float | None = None
    eye_tangents: dict | None = None
    size: tuple = (640, 480)  # per-eye pixels (width, height)
    camera: CameraModel | str = DEFAULT_CAMERA_MODEL

    def __post_init__(self):
        if isinstance(self.camera, str):
            self.camera = get_camera_model(self.camera)
        elif not isinstance(self.camera, CameraModel):
            raise ValueError(f"camera must be a camera model or its name, got {self.camera!r}")
        self.ipd = check_range("ipd", self.ipd, 0.0, MAX_CAMERA_COORDINATE)  # the eyes lie ipd / 2 off the pose
        if not (isinstance(self.fov_y, (int, float)) and self.fov_y > 0 and math.isfinite(self.fov_y)):
            raise ValueError(f"fov_y must be a finite angle > 0 degrees, got {self.fov_y}")  # the model sets the rest
        self.near = check_range("near", self.near, MIN_DISTANCE, MAX_DISTANCE)
        if self.far is not None and not self.far > self.near:  # inf is the infinite far plane
            raise ValueError(f"far ({self.far}) must be greater than near ({self.near})")
        if self.far is not None and math.isinf(self.far):
            self.far = None  # one spelling of the infinite far plane: the shaders read 0 as infinite, JSON has no inf
        if self.far is not None:
            self.far = check_range("far", self.far, self.near, MAX_DISTANCE, lo_open=True)
        if self.convergence is not None:
            self.convergence = check_range("convergence distance", self.convergence, 0.0, MAX_DISTANCE, lo_open=True)
        w, h = self.size
        if not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) for n in (w, h)) or w < 1 or h < 1:
            raise ValueError(f"image size must be whole numbers of pixels, at least 1x1, got {w!r}x{h!r}")
        self.size = (int(w), int(h))
        self.camera.check_rig(self)  # last: it looks at the eyes (e.g. the pinhole's precision limit)

    def with_size(self, size) -> "StereoRig":
        return replace(self, size=tuple(size))

    def eye(self, name: str) -> EyeView:
        if name not in EYES and name != "center":
            raise ValueError(f"eye must be one of {EYES + ('center',)}, got {name!r}")
        sign = {"left": -1.0, "right": 1.0, "center": 0.0}[name]
        offset = sign * self.ipd / 2.0
        position = self.pose.position + self.pose.rotation[:, 0] * offset
        if self.eye_tangents and name in self.eye_tangents:
            tangents = tuple(float(x) for x in self.eye_tangents[name])
        else:
            t = math.tan(math.radians(self.fov_y) / 2.0)
            a = self.size[0] / self.size[1]
            # Off-axis shear: zero parallax at the convergence distance.
            shift = -offset / self.convergence if self.convergence else 0.0
            tangents = (-t * a + shift, t * a + shift, -t, t)
        return EyeView(name, position, self.pose.rotation.copy(), tangents, self.near, self.far, self.size,
                       self.camera, self.fov_y)

    def eyes(self, which: str = "both") -> list[EyeView]:
        if which == "both":
            return [self.eye("left"), self.eye("right")]
        return [self.eye(which)]

    @classmethod
    def for_scene(cls, scene, size=(640, 480), **kw) -> "StereoRig":
        """The scene file's own camera when it has one, else a view from its +Z side that
        frames its bounds."""
        kw.setdefault("near", max(scene.extent * 1e-4, 1e-6) if scene.camera is None else 0.05)
        if scene.camera is not None:
            kw.setdefault("fov_y", scene.camera["fov_y"])
            pose = Pose(np.asarray(scene.camera["position"], float), np.asarray(scene.camera["rotation"], float))
            return cls(pose=pose, size=size, **kw)
        c = scene.center
        ext = scene.bounds[1] - scene.bounds[0]
        fov = kw.get("fov_y", 90.0)
        dist = 0.5 * max(ext[0], ext[1]) / math.tan(math.radians(fov) / 2) + ext[2] / 2
        eye = c + np.array([0.0, 0.0, max(dist, 1e-3) * 1.05])
        return cls(pose=Pose.look_at(eye, c), size=size, **kw)


# ------------------------------------------------------------------ camera paths (JSON)

def save_path(path: str | Path, poses: list[Pose], **meta) -> None:
    """Write a camera path (JSON: {"poses": [{position, rotation}, ...], ...meta}) atomically."""
    data = {"format": "rayvr-camera-path", "version": 1, **meta, "poses": [p.to_dict() for p in poses]}
    atomic_write_bytes(Path(path), json.dumps(data, indent=1, allow_nan=False).encode())


ROTATION_TOLERANCE = 1e-3  # largest |R^T R - I| entry a path file's rotation may have (rounded decimals)


def _check_pose(pose: Pose) -> str | None:
    """Why `pose` cannot be rendered, or None."""
    if pose.position.shape != (3,):
        return f"position must be 3 numbers, got shape {pose.position.shape}"
    if not (np.isfinite(pose.position).all() and np.isfinite(pose.rotation).all()):
        return "NaN or inf values"
    r = pose.rotation
    skew = float(np.abs(r.T @ r - np.eye(3)).max())
    if skew > ROTATION_TOLERANCE or np.linalg.det(r) <= 0:
        # An all-zero or scaled matrix renders nothing; a mirror (det -1) flips the image.
        return (f"rotation is not a rotation matrix (orthonormal columns, determinant +1, within "
                f"{ROTATION_TOLERANCE:g}): |R^T R - I| reaches {skew:.3g}, det {np.linalg.det(r):.3g}")
    return None


def check_camera_positions(poses, origin, where: str) -> None:
    """Refuse poses farther than MAX_CAMERA_COORDINATE from the scene's origin along an axis
    (ValueError naming `where` and the pose): the GPU's float32 maths of their rays would overflow."""
    far = np.abs(np.array([p.position for p in poses], np.float64) - np.asarray(origin, np.float64)).max(axis=1)
    bad = ~(far <= MAX_CAMERA_COORDINATE)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{where} {i}: the camera at {poses[i].position.tolist()} lies {far[i]:.3g} from the "
                         f"scene's centre along an axis; at most {MAX_CAMERA_COORDINATE:.0e} (float32 on the GPU)")


def load_path(path: str | Path) -> list[Pose]:
    """Read a camera path: {"poses": [...]} where each pose is {position, rotation} or
    {position, target, up?}. Errors name the file and the pose's index."""
    path = Path(path)
    data = read_json(path, "camera path")
    try:
        poses = data["poses"] if isinstance(data, dict) else data
        if not isinstance(poses, list):
            raise TypeError(f"'poses' must be a list, got {type(poses).__name__}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not a camera path ({exc})") from exc
    if not poses:
        raise ValueError(f"{path}: the camera path has no poses")
    out = []
    for i, d in enumerate(poses):
        try:
            pose = Pose.from_dict(d)
        except (ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{path}: pose {i}: not a pose ({type(exc).__name__}: {exc})") from exc
        problem = _check_pose(pose)
        if problem:
            raise ValueError(f"{path}: pose {i}: {problem}")
        out.append(pose)
    return out


def orbit(center, radius: float, height: float, frames: int, start_deg: float = 0.0) -> list[Pose]:
    """A turntable path around `center` (for `rayvr capture --frames N`)."""
    center = np.asarray(center, dtype=np.float64)
    poses = []
    for k in range(frames):
        a = math.radians(start_deg) + 2 * math.pi * k / frames
        eye = center + np.array([radius * math.sin(a), height, radius * math.cos(a)])
        poses.append(Pose.look_at(eye, center))
    return poses
