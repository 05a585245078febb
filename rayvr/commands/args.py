"""Arguments several commands share: argparse types with one-line errors, the stereo rig, the
camera model, and the RenderSettings a command's flags (over a config's [render] table) give."""
from __future__ import annotations

import argparse
import math

import numpy as np

from .. import settings as settings_mod
from ..util.inputs import MAX_IMAGE_SIDE
from ..gl.limits import MAX_DISTANCE  # --near, --far, --convergence, --ipd (the rig checks the rest of their ranges)

# Bounds of the numbers the command line takes beside the render options (those declare their own):
# a value outside them renders nothing useful and is refused before any work.
MAX_FRAMES = 1_000_000
MAX_BUDGET_MS = 1e6
MAX_BUDGET_HZ = 1e4
MAX_SPP = 1 << 20


def size(text: str) -> tuple[int, int]:
    try:
        w, h = text.lower().split("x")
        value = (int(w), int(h))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT (e.g. 640x480), got {text[:40]!r}") from None
    if min(value) < 1 or max(value) > MAX_IMAGE_SIDE:
        raise argparse.ArgumentTypeError(f"size must be between 1x1 and {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE}, "
                                         f"got {text!r}")
    return value


def floats(n: int):
    def parse(text: str):
        try:
            vals = [float(x) for x in text.split(",")]
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {text!r}") from None
        if len(vals) != n or not all(np.isfinite(vals)):
            raise argparse.ArgumentTypeError(f"expected {n} finite comma-separated numbers, got {text!r}")
        return vals
    return parse


def number(lo: float, hi: float, *, lo_open: bool = True, inf_ok: bool = False):
    """argparse type: a float in (lo, hi] ([lo, hi] with lo_open=False); 'inf' too if inf_ok."""
    interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]" + (" or inf" if inf_ok else "")

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number in {interval}, got {text[:40]!r}") from None
        if inf_ok and value == math.inf:
            return value
        if not (math.isfinite(value) and (value > lo if lo_open else value >= lo) and value <= hi):
            raise argparse.ArgumentTypeError(f"expected a finite number in {interval}, got {text!r}")
        return value
    return parse


def count(lo: int, hi: int):
    """argparse type: an integer in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number from {lo} to {hi}, got {text[:40]!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number from {lo} to {hi}, got {value}")
        return value
    return parse


FOV = number(0, 360)  # degrees; the camera model refuses what it cannot project (the pinhole: < 180)
IPD = number(0, MAX_DISTANCE, lo_open=False)
DISTANCE = number(0, MAX_DISTANCE)
FRAMES = count(1, MAX_FRAMES)
BUDGET_MS = number(0, MAX_BUDGET_MS)
BUDGET_HZ = number(0, MAX_BUDGET_HZ)
SPP = count(1, MAX_SPP)


def add_budget_arguments(p: argparse.ArgumentParser, help_ms: str, frame_knobs: bool = True) -> None:
    """--budget-ms or --budget-hz, and --frame-knobs (read by budget_grid)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--budget-ms", type=BUDGET_MS, help=help_ms)
    g.add_argument("--budget-hz", type=BUDGET_HZ, metavar="HZ",
                   help="the budget as a display rate: 90 is 11.1 ms a frame, 120 is 8.33 ms")
    if not frame_knobs:
        return
    p.add_argument("--frame-knobs", metavar="GRID",
                   help="with a budget: choose frame-wide knobs too, among every combination of the values given, "
                        "e.g. \"stereo=dual,reuse;spp=1,4;denoise=off,on;msaa=1,4\" (docs/budget.md)")


def budget_grid(args, given: dict, frame_knobs: tuple[str, ...], defaults: dict | None = None) -> list | None:
    """Turns --budget-hz into args.budget_ms; the --frame-knobs grid (quality/frame_knobs.py), or
    None without it. A knob the grid chooses may not also be set by a flag or the config; the
    knobs it leaves out keep what the flags and the config give, else the command's `defaults`
    (CAPTURE_DEFAULTS)."""
    from ..quality.frame_knobs import DEFAULT_KNOBS, FrameKnobs, budget_ms_of, parse_grid

    if getattr(args, "budget_hz", None) is not None:
        args.budget_ms = budget_ms_of(args.budget_hz)
    text = getattr(args, "frame_knobs", None)
    if text is None:
        return None
    if args.budget_ms is None:
        raise ValueError("--frame-knobs goes with --budget-ms or --budget-hz")
    d = DEFAULT_KNOBS
    values = {**(defaults or {}), **given}
    base = FrameKnobs(stereo=values.get("stereo", d.stereo), spp=getattr(args, "spp", d.spp),
                      denoise=values.get("denoise", d.denoise), msaa=values.get("msaa", d.msaa),
                      temporal=values.get("temporal", d.temporal),
                      iterations=values.get("denoise_iterations", d.iterations))
    grid = parse_grid(text, base)
    for part in text.split(";"):
        knob = part.partition("=")[0].strip().lower()
        if not knob:
            continue
        if knob not in frame_knobs:
            raise ValueError(f"--frame-knobs: {knob} is not a knob this command chooses (it takes "
                             f"{', '.join(frame_knobs)})")
        if knob in given or (knob == "spp" and getattr(args, "spp", 1) != 1):
            raise ValueError(f"--frame-knobs chooses {knob}: leave out --{knob} (and the config's [render] {knob})")
    return grid


def add_device_argument(p) -> None:
    """--device N: the EGL device (GPU) every headless context of the command takes (cli.py applies it)."""
    p.add_argument("--device", type=count(0, 63), metavar="N",
                   help="the EGL device (GPU) to render on, by its index in `rayvr info`'s list (default: "
                        "the driver's first; the environment variable RAYVR_EGL_DEVICE does the same)")


def add_pose_arguments(g) -> None:
    """Where the rig stands and how its eyes look (capture, preview: rig_keywords reads them)."""
    # --pose, not --camera: the camera model is --camera-model (the old spelling still works)
    g.add_argument("--pose", "--camera", dest="pose", type=floats(6), metavar="EX,EY,EZ,TX,TY,TZ",
                   help="the rig's position and look-at target (default: the scene's camera or a framing view; "
                        "--camera is the old name)")
    g.add_argument("--fov", type=FOV, help="vertical field of view in degrees (the camera model sets the limit)")
    g.add_argument("--ipd", type=IPD, default=0.064, help="interpupillary distance in scene units (default 0.064)")
    g.add_argument("--convergence", type=DISTANCE, help="zero-parallax distance (default: parallel eyes, as HMDs)")


def add_rig_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("camera / stereo rig")
    g.add_argument("--size", type=size, default=(640, 480), help="per-eye image size WxH (default 640x480)")
    add_pose_arguments(g)
    g.add_argument("--near", type=DISTANCE, help="near plane distance")
    g.add_argument("--far", type=number(0, MAX_DISTANCE, inf_ok=True),
                   help="far plane distance, greater than near (default: infinite, reversed-Z)")


def add_camera_model_arguments(p: argparse.ArgumentParser) -> None:
    """The camera model and its parameters (capture, preview, bench, info --graph); its sub-rays
    (--msaa, --ssaa, --tile-culling) are render options."""
    from ..frame.cameras import CAMERA_MODELS, DEFAULT_CAMERA_MODEL

    g = p.add_argument_group("camera model")
    g.add_argument("--camera-model", choices=tuple(CAMERA_MODELS), default=DEFAULT_CAMERA_MODEL,
                   help="how each eye makes its rays; every model but the pinhole casts its primary rays "
                        "(" + "; ".join(f"{n}: {m.doc}" for n, m in CAMERA_MODELS.items() if m.doc) + ")")
    g.add_argument("--camera-param", action="append", metavar="KEY=VALUE",
                   help="a camera model parameter, repeatable: " + "; ".join(  # each model's own (param_syntax)
                       f"{n} {m.param_help()}" for n, m in CAMERA_MODELS.items() if m.parameters()))


def add_render_arguments(p: argparse.ArgumentParser, command: str) -> None:
    """The camera model's flags and every render option `command` offers (generated)."""
    add_camera_model_arguments(p)
    settings_mod.add_arguments(p, command)


# What `rayvr capture` renders, where neither a flag nor the config's [render] table says, beyond
# RenderSettings' defaults (which the Python API and the preview keep): the denoiser on, so that
# the first image, the built-in room at one sample a pixel, is clean in seconds on a CPU (its
# fireflies clamped, its penumbrae smooth: docs/usage.md). Only the sampled effects' pixels are
# filtered: a scene of one's own, all `raster` by default, runs no denoiser.
CAPTURE_DEFAULTS = {"denoise": True}


def add_capture_default_arguments(p: argparse.ArgumentParser) -> None:
    """The switches that turn CAPTURE_DEFAULTS off (capture; info --graph, which shows a capture's)."""
    p.add_argument("--no-denoise", dest="denoise", action="store_false", default=None,
                   help="leave the denoiser off: the raw samples (a capture denoises the sampled effects "
                        "unless told otherwise, here or by the config's [render] denoise = false)")


def with_capture_defaults(given: dict) -> dict:
    """The option values a capture runs with: CAPTURE_DEFAULTS under `given` (render_values')."""
    return settings_mod.merged(CAPTURE_DEFAULTS, given)


def render_values(args, command: str, config=None, **fixed) -> dict:
    """The render option values a command runs with: a config's [render] table, then the flags
    given, then `fixed` (what the command itself sets), with what each implies."""
    return settings_mod.merged(getattr(config, "render", None) or {}, settings_mod.given_by_args(args, command), fixed)


def settings_from_args(args, command: str, config=None, **fixed):
    """RenderSettings of render_values (options not given keep their defaults)."""
    from ..renderer import RenderSettings

    return RenderSettings(**render_values(args, command, config, **fixed))


def camera_from_args(args, settings=None, given: dict | None = None):
    """The camera model --camera-model and --camera-param ask for; `settings` (and the options
    `given`) are checked against it."""
    from ..frame.cameras import CAMERA_MODELS, get_camera_model, parse_camera_params

    if getattr(args, "convergence", None) is not None and not CAMERA_MODELS[args.camera_model].converges:
        # a model that maps angles has no planar frustum to shear (CameraModel.converges)
        raise ValueError(f"--convergence shears the eyes' planar frusta to zero parallax at a distance; the "
                         f"{args.camera_model} camera's eyes have none and stay parallel: leave out --convergence")
    camera = get_camera_model(args.camera_model, **parse_camera_params(args.camera_model, args.camera_param))
    msaa = settings.msaa if settings is not None else getattr(args, "msaa", None) or 1
    if (given or {}).get("primary") == "raster" and (msaa > 1 or not camera.rasterizable):
        # the renderer casts primary rays then (Renderer.plan): say so rather than ignore the flag
        why = f"--msaa {msaa} casts sub-rays" if msaa > 1 else f"the {camera.name} camera cannot be rasterized"
        raise ValueError(f"--primary raster: {why}, so primary visibility is ray-cast; leave out --primary raster")
    return camera


def rig_keywords(args, camera) -> dict:
    """StereoRig keywords of the rig flags given (add_pose_arguments; --near and --far where the
    command has them)."""
    kw = {"ipd": args.ipd, "camera": camera}
    for key, attr in (("fov_y", "fov"), ("convergence", "convergence"), ("near", "near"), ("far", "far")):
        if getattr(args, attr, None) is not None:
            kw[key] = getattr(args, attr)
    return kw


def rig_from_args(args, scene, camera):
    """--pose's rig, else the scene's first view (app/viewpoint.py: inside an interior)."""
    from ..app.viewpoint import first_rig
    from ..frame.cameras.rig import Pose, StereoRig

    if not args.pose:
        return first_rig(scene, args.size, **rig_keywords(args, camera))
    rig = StereoRig.for_scene(scene, size=args.size, **rig_keywords(args, camera))
    rig.pose = Pose.look_at(args.pose[:3], args.pose[3:])
    return rig


def add_connect_timeout_argument(p: argparse.ArgumentParser) -> None:
    from ..app.cluster import DEFAULT_CONNECT_TIMEOUT_S

    p.add_argument("--connect-timeout", type=number(0, 86400), metavar="SECONDS",
                   help=f"with --address: give up on a Ray cluster that does not answer within this time "
                        f"(default {DEFAULT_CONNECT_TIMEOUT_S:g} s)")


def connect_timeout(args) -> float:
    from ..app.cluster import DEFAULT_CONNECT_TIMEOUT_S

    return DEFAULT_CONNECT_TIMEOUT_S if args.connect_timeout is None else args.connect_timeout
