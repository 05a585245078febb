"""The camera-model contract: a model turns an eye (rayvr.frame.cameras.rig.EyeView) into rays, once as a
numpy reference (`rays`) and once in GLSL (the file named by `glsl`), and the two must agree.

Conventions shared by every model:
- numpy arrays are image rows top-down, as EyeView.ray_directions and the frames returned to
  users; pixel (x, y) has its centre at (x + 0.5, y + 0.5).
- A model's own maths (`ray_at`, and its GLSL twin `camera_ray_at`) works in GL image
  coordinates: x right, y *up* (row 0 is the bottom row), centres at +0.5, so the numpy and GLSL
  code read alike; `rays()` turns that into top-down arrays.
- numpy origins are world positions (float64); GLSL origins are scene-local (world minus the
  scene origin, which is what `uniforms(eyes, origin)` subtracts), as every G-buffer position is.

A camera *sample* is a pixel of the eye image (the G-buffer is one sample per pixel). A model may
leave pixels without a sample (`footprint` 0: outside a fisheye's sphere, between a foveated
pattern's samples) and may give a sample a footprint wider than a pixel (foveated). Sub-rays
(MSAA/SSAA for rays, thin-lens positions) come from the low-discrepancy set of sampling.py:
sub-ray i of N goes through `centre + offset_i * footprint` and lens point `lens_i`.

The GLSL contract (a model's file, `glsl`, is included by glsl/common/camera.glsl through the
CAMERA_MODEL_FILE define of `defines()`; camera.glsl declares the per-eye uniforms and builds
camera_ray / camera_subray / the neighbours from these two; the model may declare more uniforms,
named camera_*):

    // the ray through continuous image position `pixel` and unit-disk lens point `lens`;
    // false where that position makes no ray (e.g. beyond a fisheye's 180 degrees)
    bool camera_ray_at(int eye, vec2 pixel, vec2 size, vec2 lens, out vec3 origin, out vec3 direction);
    // the footprint side (pixels) of the sample at pixel centre `pixel`; 0: no sample there
    float camera_footprint(int eye, vec2 pixel, vec2 size);

A sparse model (`sparse`: footprint 0 between its samples) fills the gaps for display with its own
GLSL file, `reconstruction`, which glsl/shade/sample_resolve.comp includes after declaring the
images `sum` (the samples' accumulated colour), `fill` (rgba32f, kept between dispatches) and
`frame_hdr` (the displayed colour), the uniform `exposure` and the helpers is_sample, compress
and expand (the units tonemap shows):

    // pixel p.xy of eye layer p.z of an n-pixel image, once per dispatch of resolve_steps(),
    // whose uniforms it reads; the last dispatch writes frame_hdr at every pixel
    void camera_resolve(ivec3 p, ivec2 n);

`reconstruct` is its numpy twin (a test compares them).

A model is added by `register_camera_model(cls)` (rayvr's own through the same function), from
inside rayvr or outside it: it then has a name in CAMERA_MODELS and a CAMERA_<NAME> id in the
generated header (layout.glsl), which every program compiled afterwards sees.

Per-colour-channel sample sets (HMD chromatic pre-correction, HVVR's split-colour samples):
`channels` C > 1 makes the frame cast its primary rays once per channel (`rays(eye, channel=c)`,
GLSL camera_sample_channel(), which a model's GLSL reads: the uniform camera_channel, or the set a
kernel making several sets' rays names) and take channel c of each set's colour (frame/passes/sample_accumulate.py).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from ...gl.glsl_constants import declare
from ...gl.limits import to_float32
from ...gl.shaders import GLSL_DIR
from .sampling import subsamples

if TYPE_CHECKING:  # rayvr.frame.cameras.rig imports this package; the eye is only a type here
    from .rig import EyeView, StereoRig

DIFFERENCE_STEP = 1e-3  # pixels: central differences of ray_at give the footprints (error ~1e-9)


@dataclass(frozen=True)
class CameraRays:
    """One eye's camera rays, rows top-down, world space (see the module notes).

    origins     (H, W, 3) float64 world positions
    directions  (H, W, 3) unit directions
    ddx, ddy    (H, W, 3) footprints: the derivative of the unit direction per footprint step
                (one pixel, or a foveated sample's spacing) along +x (one column right) and along
                +y of the array (one row *down*); GL's "up" neighbour is therefore direction - ddy.
                Both are orthogonal to the direction.
    valid       (H, W) bool: False where the sample makes no ray (its other values are then
                meaningless)
    """

    origins: np.ndarray
    directions: np.ndarray
    ddx: np.ndarray
    ddy: np.ndarray
    valid: np.ndarray


def pixel_grid(size) -> tuple[np.ndarray, np.ndarray]:
    """GL coordinates (x right, y up) of the pixel centres, as (H, W) arrays rows top-down."""
    w, h = size
    x = np.broadcast_to(np.arange(w) + 0.5, (h, w))
    y = np.broadcast_to((h - np.arange(h) - 0.5)[:, None], (h, w))
    return x, y


def normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


class CameraModel:
    """Base of every camera model. Instances are immutable values (models are frozen
    dataclasses whose fields are the model's parameters), one per rig; per-eye parameters (an
    HMD's lens per eye) are derived from EyeView.name inside the model."""

    name: ClassVar[str]
    # Capabilities the frame reads from the model, never from its name:
    # a planar frustum per eye, which a rasterizer samples, render tiles cut into off-axis parts,
    # reprojection (--temporal, warp, reuse) maps between and screen-space rays are straight in
    rasterizable: ClassVar[bool] = False
    # the frame's tile frustum culling is on by default at several sub-rays per sample (where it
    # measured faster on the GPU: primary_rays.culls_tiles)
    culls_tiles_by_default: ClassVar[bool] = True
    # the eyes' images lie on planar frusta that StereoRig.convergence shears off-axis (zero parallax
    # at a distance); False: the eyes map angles and stay parallel, and --convergence is refused
    converges: ClassVar[bool] = True
    # depth (frames, G-buffer) is the distance along each pixel's ray, not the view depth along -Z
    # (near and far are spheres): what the written camera files say their depth is
    depth_along_ray: ClassVar[bool] = False
    # a field of view past what a planar frustum holds (up to and beyond 180 degrees): the model the
    # planar models' errors advise for such fields
    wide_angle: ClassVar[bool] = False
    # the model's own parameter for a lens (depth of field), if it has one: what the refusal of
    # the frame's --dof-diameter blur points to instead
    lens_parameter: ClassVar[str | None] = None
    # its image is the pinhole's, however sampled, so the pinhole reference judges its error: a
    # budget pick may choose it (--frame-knobs camera=, quality/frame_knobs.py)
    judged_by_pinhole: ClassVar[bool] = False
    glsl: ClassVar[str]  # the model's GLSL file: relative to rayvr/glsl/, or absolute (a model outside rayvr)
    channels: ClassVar[int] = 1  # colour channel sets (a model may make it a property)
    # samples leave pixels between them, which `reconstruction` fills for display
    sparse: ClassVar[bool] = False
    # a sparse model's fill (frame/passes/sample_resolve.py): its GLSL file (as `glsl`), defining
    # `void camera_resolve(ivec3 p, ivec2 n)`, run over every pixel once per resolve_steps() entry;
    # `reconstruct` is its numpy twin
    reconstruction: ClassVar[str | None] = None
    doc: ClassVar[str] = ""
    # --camera-param's help: each parameter's value syntax (KEY=SYNTAX); one left out reads VALUE
    param_syntax: ClassVar[dict] = {}

    @classmethod
    def glsl_id(cls) -> str:
        """The model's id in the generated header (register_camera_model declares it): the value of
        the CAMERA_MODEL define, which shaders compare (`#if CAMERA_MODEL == CAMERA_WIDE`)."""
        return "CAMERA_" + cls.name.upper()

    @classmethod
    def glsl_path(cls) -> Path:
        """The model's GLSL file (`glsl` under rayvr/glsl/; an absolute `glsl` is itself)."""
        return GLSL_DIR / cls.glsl

    @classmethod
    def defines(cls) -> dict:
        """What a program that includes common/camera.glsl needs from the model: its id, its GLSL
        file (the include's path) and the declared capabilities the shaders read."""
        return {"CAMERA_MODEL": cls.glsl_id(), "CAMERA_MODEL_FILE": cls.glsl,
                "CAMERA_DEPTH_ALONG_RAY": int(cls.depth_along_ray)}

    @classmethod
    def parameters(cls) -> dict:
        """{name: (type, default)} of the model's parameters (its dataclass fields)."""
        return {f.name: (f.type, f.default) for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else {}

    @classmethod
    def param_help(cls) -> str:
        """The model's parameters as --camera-param's help spells them: `KEY=SYNTAX ...`."""
        return " ".join(f"{key}={cls.param_syntax.get(key, 'VALUE')}" for key in cls.parameters())

    def check_rig(self, rig: "StereoRig") -> None:
        """Refuse rig settings this model cannot render (ValueError); nothing by default."""

    # -- numpy reference --------------------------------------------------------------
    def ray_at(self, eye: "EyeView", channel: int, x, y, lens) -> tuple:
        """Rays through GL image positions (x, y) (arrays of one shape) and lens point `lens`
        (2 numbers, unit disk): (origins (..., 3) world, unit directions (..., 3), valid (...))."""
        raise NotImplementedError

    def footprint(self, eye: "EyeView", channel: int = 0) -> np.ndarray:
        """(H, W) rows top-down: the footprint side in pixels of the sample at each pixel,
        0 where there is no sample. One sample per pixel by default."""
        return np.ones(eye.size[::-1])

    def rays(self, eye: "EyeView", channel: int = 0, subsample: tuple | None = None) -> CameraRays:
        """The rays of every sample of `eye` (rows top-down): through the sample centres and the
        lens centre, or sub-ray `subsample` = (i, n) of the low-discrepancy set (sampling.py)."""
        self._check_channel(channel)
        x, y = pixel_grid(eye.size)
        f = self.footprint(eye, channel)
        offset, lens = np.zeros(2), np.zeros(2)
        if subsample is not None:
            offsets, lenses = subsamples(subsample[1])
            offset, lens = offsets[subsample[0]], lenses[subsample[0]]
        x, y = x + offset[0] * f, y + offset[1] * f
        origins, d, valid = self.ray_at(eye, channel, x, y, lens)
        h = DIFFERENCE_STEP * np.where(f > 0, f, 1.0)[..., None]
        hs = h[..., 0]
        ddx = (self.ray_at(eye, channel, x + hs, y, lens)[1] - self.ray_at(eye, channel, x - hs, y, lens)[1]) / (2 * h) * f[..., None]
        ddy = -(self.ray_at(eye, channel, x, y + hs, lens)[1] - self.ray_at(eye, channel, x, y - hs, lens)[1]) / (2 * h) * f[..., None]
        ddx -= d * np.sum(ddx * d, axis=-1, keepdims=True)  # derivatives of unit vectors are orthogonal to them
        ddy -= d * np.sum(ddy * d, axis=-1, keepdims=True)
        return CameraRays(np.broadcast_to(origins, d.shape), d, ddx, ddy, valid & (f > 0))

    # -- the frame for display ------------------------------------------------------------
    def resolve_steps(self) -> list[dict]:
        """The dispatches of the frame's resolve (frame/passes/sample_resolve.py), in order: the
        uniform values of each (a sparse model's `reconstruction` reads them); the last writes
        the frame. One dispatch by default: the samples as they are."""
        return [{}]

    def reconstruct(self, eye: "EyeView", image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
        """The numpy twin of the resolve: the displayed colour ((H, W, C) linear, rows top-down) of
        `image`, which holds the samples' colour (0 between them); `exposure` is what tonemap
        multiplies by. The samples as they are by default."""
        return image

    def _check_channel(self, channel: int) -> None:
        if not 0 <= channel < self.channels:
            raise ValueError(f"camera model {self.name!r} has {self.channels} channel set(s), got channel {channel}")

    # -- GPU ----------------------------------------------------------------------------
    def uniforms(self, eyes: list["EyeView"], origin) -> dict:
        """Values of the per-eye uniforms of glsl/common/camera.glsl (float32 numpy arrays,
        GLSL layout), for up to two eyes (index = layer). A model with its own uniforms adds
        them to this dict. Both eyes share one model (their shaders are built for one)."""
        others = {e.camera.name for e in eyes} - {self.name}
        if others:
            raise ValueError(f"the eyes of one frame must share a camera model: {self.name!r} and {sorted(others)}")
        origin = np.asarray(origin, dtype=np.float64)
        position = np.zeros((2, 3))
        rotation = np.zeros((2, 3, 3), np.float32)
        tangents = np.zeros((2, 4), np.float32)
        for i, eye in enumerate(eyes):
            position[i] = eye.position - origin  # float64 subtraction first: far-off rigs stay exact
            rotation[i] = eye.rotation.T  # GLSL mat3 is column-major
            tangents[i] = np.nan_to_num(np.asarray(eye.tangents, np.float64), posinf=3e38, neginf=-3e38)
        return {"eye_position": to_float32("camera position (scene-local)", position), "eye_rotation": rotation,
                "eye_tangents": tangents,
                "eye_depth": to_float32("near, far", [eyes[0].near, eyes[0].far or 0.0])}

    def bind(self, gl) -> None:
        """Bind GL resources the model's GLSL reads (textures); nothing by default."""

    # -- camera files -------------------------------------------------------------------
    def transforms_fields(self, eye: "EyeView") -> dict:
        """The camera of one eye image as nerfstudio's transforms.json spells it (rayvr/app/views.py):
        camera_model, its intrinsics (pixels, rows top-down, centres at +0.5) and distortion,
        exactly the camera rayvr renders; ValueError (not_described) where none of nerfstudio's
        models is this camera, as by default.

        nerfstudio (cameras/cameras.py) maps pixel (x, y) to c = ((x - cx) / fl_x, -(y - cy) / fl_y), then
        OPENCV: direction (c, -1) after undistorting c (here no distortion: k = p = 0);
        OPENCV_FISHEYE: theta = |c|, direction (sin(theta) c / theta, -cos(theta)) (k1..k4 = 0);
        EQUIRECTANGULAR: yaw pi c_x, pitch pi c_y (any fl: sections of the sphere too)."""
        raise self.not_described("no camera_model is written for it")

    def not_described(self, why: str) -> ValueError:
        """The error of transforms_fields for a camera nerfstudio's models cannot describe."""
        return ValueError(f"transforms.json (nerfstudio's camera models) cannot describe the {self.name} camera: {why}")


def planar_transforms_fields(eye: "EyeView") -> dict:
    """transforms_fields of an eye's undistorted planar frustum (its tangents): OPENCV."""
    (w, h), (l, r, b, t) = eye.size, eye.tangents
    return {"camera_model": "OPENCV", "fl_x": w / (r - l), "fl_y": h / (t - b), "cx": -l * w / (r - l),
            "cy": t * h / (t - b), "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
            "camera_angle_x": math.atan(r) - math.atan(l), "camera_angle_y": math.atan(t) - math.atan(b)}

# The camera models by name, in registration order (register_camera_model; the package,
# rayvr/frame/cameras/__init__.py, registers rayvr's own), so a model reads the others' traits here.
CAMERA_MODELS: dict[str, type[CameraModel]] = {}
# The CAMERA_<NAME> id of each model name ever registered: 1, 2, ... in registration order. A name
# keeps its id when unregistered (the header's constant cannot change), so no id is given twice.
_CAMERA_IDS: dict[str, int] = {}


def register_camera_model(cls: type[CameraModel]) -> type[CameraModel]:
    """Add camera model `cls` to CAMERA_MODELS and declare its CAMERA_<NAME> id in the generated
    header, for programs compiled from then on; returns `cls` (a class decorator too). Refuses, in
    one line, what is not a CameraModel subclass, a name that is no identifier or is taken (its id
    included: names differing in case only), a GLSL file that does not exist, sparse samples without
    a reconstruction file (or a reconstruction without sparse samples), and param_syntax for a
    parameter the model does not have."""
    what = getattr(cls, "__qualname__", repr(cls))
    if not (isinstance(cls, type) and issubclass(cls, CameraModel)):
        raise TypeError(f"camera model {what}: not a subclass of rayvr.frame.cameras.CameraModel")
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"camera model {what}: its name must be an identifier, got {name!r}")
    taken = [n for n in CAMERA_MODELS if n.upper() == name.upper()]
    if taken:
        raise ValueError(f"camera model {what}: the name {name!r} is taken by the registered "
                         f"{CAMERA_MODELS[taken[0]].__qualname__} ({taken[0]!r})")
    glsl = getattr(cls, "glsl", None)
    if not isinstance(glsl, str) or not glsl:
        raise ValueError(f"camera model {name!r}: `glsl` must name its GLSL file (under rayvr/glsl/ or absolute)")
    if not cls.glsl_path().is_file():
        raise ValueError(f"camera model {name!r}: its GLSL file {cls.glsl_path()} does not exist")
    if cls.sparse or cls.reconstruction is not None:  # a fill exists exactly for sparse samples
        if not cls.sparse:
            raise ValueError(f"camera model {name!r}: a `reconstruction` fills the pixels between sparse samples; "
                             f"declare sparse = True or leave it out")
        if not isinstance(cls.reconstruction, str) or not (GLSL_DIR / cls.reconstruction).is_file():
            raise ValueError(f"camera model {name!r}: sparse samples need `reconstruction`, the GLSL file that fills "
                             f"the pixels between them; got {cls.reconstruction!r}, which is no file")
    unknown = [key for key in cls.param_syntax if key not in cls.parameters()]
    if unknown:
        raise ValueError(f"camera model {name!r}: param_syntax names {unknown[0]!r}, which is none of its "
                         f"parameters ({', '.join(cls.parameters()) or 'none'})")
    declare(f"CAMERA_{name.upper()}", _CAMERA_IDS.setdefault(name.upper(), len(_CAMERA_IDS) + 1))
    CAMERA_MODELS[name] = cls
    return cls


def unregister_camera_model(name: str) -> None:
    """Take model `name` out of CAMERA_MODELS (a test's own model); its id stays declared."""
    CAMERA_MODELS.pop(name, None)
