"""The `rayvr` command: capture, info, bench, preview."""
from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
import os
import signal
import sys
from pathlib import Path

import numpy as np

from .accumulation import MAX_DENOISE_ITERATIONS
from .limits import MAX_DISTANCE  # --near, --far, --convergence, --ipd (the rig checks the rest of their ranges)
from .accel.bvh import BUILDS
from .accel.gpu import DEFAULT_TRAVERSAL, parse_traversal
from .extras import MissingExtraError, require
from .gpu_layout import BVH_LAYOUTS
from .inputs import MAX_IMAGE_SIDE
from .signals import handling


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = text.lower().split("x")
        size = (int(w), int(h))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT (e.g. 640x480), got {text[:40]!r}") from None
    if min(size) < 1 or max(size) > MAX_IMAGE_SIDE:
        raise argparse.ArgumentTypeError(f"size must be between 1x1 and {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE}, "
                                         f"got {text!r}")
    return size


def _floats(n: int):
    def parse(text: str):
        try:
            vals = [float(x) for x in text.split(",")]
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {text!r}") from None
        if len(vals) != n or not all(np.isfinite(vals)):
            raise argparse.ArgumentTypeError(f"expected {n} finite comma-separated numbers, got {text!r}")
        return vals
    return parse


# Bounds of the numbers the command line takes: a value outside them renders nothing useful
# (black, empty, or float32 overflow in the shaders) and is refused before any work.
MAX_EXPOSURE = 1e6   # x1e6 already turns any lit pixel white
MAX_FRAMES = 1_000_000
MAX_BUDGET_MS = 1e6


def _number(lo: float, hi: float, *, lo_open: bool = True, inf_ok: bool = False):
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


def _count(lo: int, hi: int):
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


def _prefix(text: str) -> str:
    from .output import check_file_prefix

    try:
        return check_file_prefix(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _worker_counts(text: str) -> str:
    """argparse type: comma-separated worker counts, each from 1 to 1024 (kept as text)."""
    try:
        counts = [int(x) for x in text.split(",")]
    except ValueError:
        counts = []
    if not counts or not all(1 <= c <= 1024 for c in counts):
        raise argparse.ArgumentTypeError(f"expected worker counts from 1 to 1024, comma-separated, got {text[:40]!r}")
    return text


FOV = _number(0, 360)  # degrees; the camera model refuses what it cannot project (the pinhole: < 180)
IPD = _number(0, MAX_DISTANCE, lo_open=False)
DISTANCE = _number(0, MAX_DISTANCE)
FRAMES = _count(1, MAX_FRAMES)
BUDGET_MS = _number(0, MAX_BUDGET_MS)
MAX_SPP = 1 << 20
SPP = _count(1, MAX_SPP)
DENOISE_ITERATIONS = _count(1, MAX_DENOISE_ITERATIONS)
SEED = _count(0, 2**32 - 1)  # the shaders' frame_seed is a uint
REPEAT = _count(1, 100_000)  # bench --repeat: timed frames per measurement


def add_rig_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("camera / stereo rig")
    g.add_argument("--size", type=_size, default=(640, 480), help="per-eye image size WxH (default 640x480)")
    g.add_argument("--camera", type=_floats(6), metavar="EX,EY,EZ,TX,TY,TZ",
                   help="eye position and look-at target (default: the scene's camera or a framing view)")
    g.add_argument("--fov", type=FOV, help="vertical field of view in degrees (the camera model sets the limit)")
    g.add_argument("--ipd", type=IPD, default=0.064, help="interpupillary distance in scene units (default 0.064)")
    g.add_argument("--convergence", type=DISTANCE, help="zero-parallax distance (default: parallel eyes, as HMDs)")
    g.add_argument("--near", type=DISTANCE, help="near plane distance")
    g.add_argument("--far", type=_number(0, MAX_DISTANCE, inf_ok=True),
                   help="far plane distance, greater than near (default: infinite, reversed-Z)")


def add_stereo_argument(p: argparse.ArgumentParser, more: str = "", warp_layers: bool = False) -> None:
    from .stereo import STEREO_MODES

    p.add_argument("--stereo", choices=STEREO_MODES, default="dual",
                   help="how the second eye is made: dual renders both; warp synthesizes both from a central view "
                        "through its screen-space quadtree; reuse gives the right eye the left eye's shading where "
                        f"it sees the same surface{more} (default dual)")
    if warp_layers:
        p.add_argument("--warp-layers", type=int, choices=(1, 2), default=2,
                       help="depth layers of the central view warp traces: 2 (default) finds what lies behind its "
                            "first surfaces (the second layer, --second-layer), 1 inpaints those disocclusions")


def add_camera_arguments(p: argparse.ArgumentParser, msaa_default: int | None = 1) -> None:
    """The camera model and its sub-rays (capture, preview, bench, info --graph)."""
    from .cameras import CAMERA_MODELS
    from .cameras.sampling import SAMPLE_COUNTS

    g = p.add_argument_group("camera model and anti-aliasing")
    g.add_argument("--camera-model", choices=tuple(CAMERA_MODELS), default="pinhole",
                   help="how each eye makes its rays; every model but the pinhole casts its primary rays "
                        "(" + "; ".join(f"{n}: {m.doc}" for n, m in CAMERA_MODELS.items() if m.doc) + ")")
    g.add_argument("--camera-param", action="append", metavar="KEY=VALUE",
                   help="a camera model parameter, repeatable: distorted coefficients=K1,K2,K3[/K1,K2,K3/K1,K2,K3] "
                        "center=CX,CY samples=FILE; wide mapping=spherical|equidistant fov_x=DEG; foveated "
                        "gaze=X,Y fovea_mar=DEG mar_slope=S fovea_radius=DEG; dof aperture=R focus=D")
    g.add_argument("--msaa", type=int, choices=SAMPLE_COUNTS, default=msaa_default,
                   help="sub-rays per sample (anti-aliasing; casts primary rays): shading once per pixel per "
                        "distinct triangle, or per sub-ray with --ssaa")
    g.add_argument("--ssaa", action="store_true", help="shade every sub-ray of --msaa N (supersampling)")
    g.add_argument("--tile-culling", action=argparse.BooleanOptionalAction, default=None,
                   help="ray-cast primary visibility culls the BVH per 16x8-pixel tile first (a frustum over every "
                        "sub-ray, lens point and channel of the tile; the same hits, exact) and walks the binary "
                        "layout (default: with --msaa above 1 except foveated and dof cameras, where it measured "
                        "faster); bench primary: each rays row without and with it (default: as the renderer "
                        "chooses)")


def camera_from_args(args):
    """The camera model --camera-model and --camera-param ask for."""
    from .cameras import get_camera_model, parse_camera_params

    if getattr(args, "convergence", None) is not None and args.camera_model == "wide":
        # The wide camera maps angles, not a planar frustum: there is nothing to shear (cameras/wide.py).
        raise ValueError("--convergence shears the eyes' planar frusta to zero parallax at a distance; the wide "
                         "camera's eyes have none and stay parallel: leave out --convergence")
    camera = get_camera_model(args.camera_model, **parse_camera_params(args.camera_model, args.camera_param))
    msaa = getattr(args, "msaa", 1) or 1
    if getattr(args, "primary", None) == "raster" and (msaa > 1 or not camera.rasterizable):
        # the renderer casts primary rays then (Renderer.plan): say so rather than ignore the flag
        why = f"--msaa {msaa} casts sub-rays" if msaa > 1 else f"the {camera.name} camera cannot be rasterized"
        raise ValueError(f"--primary raster: {why}, so primary visibility is ray-cast; leave out --primary raster")
    return camera


def settings_from_args(args, **kw):
    """RenderSettings from the flags a command has (the others keep their defaults)."""
    from .renderer import RenderSettings

    for key in ("exposure", "tonemapper", "layer_mode", "primary", "msaa", "ssaa", "bvh_build", "tile_culling"):
        if getattr(args, key, None) is not None:
            kw.setdefault(key, getattr(args, key))
    return RenderSettings(**kw)


def rig_from_args(args, scene):
    from .camera import Pose, StereoRig

    kw = {"ipd": args.ipd, "camera": camera_from_args(args)}
    for key, attr in (("fov_y", "fov"), ("convergence", "convergence"), ("near", "near"), ("far", "far")):
        if getattr(args, attr) is not None:
            kw[key] = getattr(args, attr)
    rig = StereoRig.for_scene(scene, size=args.size, **kw)
    if args.camera:
        rig.pose = Pose.look_at(args.camera[:3], args.camera[3:])
    return rig


def _file_identity(path) -> dict | None:
    """A file's identity for resuming a capture: its path, size and modification time."""
    if path is None:
        return None
    try:
        st = Path(path).stat()
    except OSError:  # the loader says what is wrong with it
        return {"path": str(path)}
    return {"path": str(Path(path).resolve()), "bytes": st.st_size, "mtime_ns": st.st_mtime_ns}


def _capture_poses(args, rig, scene):
    """(poses, per-frame rig overrides or None) of --views, --path, --frames or the rig's pose."""
    from .capture import poses_for

    if args.views:
        from .views import views_for

        return views_for(args.views, scene, rig)
    return poses_for(rig, scene, args.frames, args.path), None


def _print_capture(args, summary, summary_path, scene_summary) -> None:
    if not args.quiet:
        print(scene_summary)
        print(f"wrote {len(summary['files'])} files to {args.out}/ ({summary['frames']} frame(s), {args.eye} eye(s))")
        counts = [f"{summary[k]} {k}" for k in ("written", "skipped", "retried", "failed") if k in summary]
        print("frames: " + ", ".join(counts))
    if args.timings:
        print("GPU ms per pass (mean over frames; GL timer queries):")
        for k in summary["passes"]:
            v = summary["gpu_ms_mean"].get(k)
            print(f"  {k:12s} {v:9.3f}" if v is not None else f"  {k:12s} unavailable (the timer read back garbage)")
        print(f"  {'total':12s} {sum(summary['gpu_ms_mean'].values()):9.3f}   ({summary['gl']})")
        if not summary["timings_meaningful"]:
            print("  note: software rasterizer: GL timer queries do not measure GPU work here; "
                  "benchmark on a GPU")
        print(f"timings saved to {summary_path}")


def cmd_capture(args) -> int:
    from .cameras import CAMERA_MODELS
    from .capture import CaptureJob, JobFolder, job_identity, run_capture, write_summary
    from .output import check_output_dir
    from .renderer import Renderer, RenderSettings

    if args.budget_ms is not None:
        require("flip_evaluator", "--budget-ms")  # it predicts image error with FLIP, before any work
    if not args.workers and (args.address or args.chunk or args.connect_timeout is not None):
        raise ValueError("--address, --connect-timeout and --chunk go with --workers N")
    if args.workers:
        from .cluster import require_ray

        require_ray()  # the optional extra, before any work
        if args.budget_ms is not None:
            raise ValueError("--budget-ms picks effects on this machine's GPU; run it without --workers and "
                             "pass the config it reports with --materials")
        if args.temporal:
            raise ValueError("--temporal carries each frame's samples into the next, so its frames render in "
                             "order in one process; leave out --workers")
    if args.temporal and not CAMERA_MODELS[args.camera_model].rasterizable:
        raise ValueError(f"--temporal reprojects the last frame's samples through the eyes' planar frusta, "
                         f"which the {args.camera_model} camera does not have: leave out --temporal")
    check_output_dir(args.out)  # fail before any rendering work; the folder is made with the first file
    if args.quiet:
        from .accel.sbvh import set_progress_bars

        set_progress_bars(False)  # the BVH build's bar, which the Renderer starts deep inside a frame
    if args.format == "exr":
        from .output import openexr

        openexr()  # the optional package, before any work
    aux = tuple(a for a in (args.aux or "").split(",") if a)
    if args.stereo == "warp" and args.format == "exr" and args.eye == "both" and args.view == "color":
        raise ValueError("--format exr writes the linear HDR colour, which --stereo warp does not make "
                         "(it warps the displayed colour): use --stereo dual or reuse")
    if args.views and "depth" not in aux:
        aux += ("depth",)  # a multi-view capture writes depth beside every view
    settings = RenderSettings(exposure=args.exposure, tonemapper=args.tonemapper, layer_mode=args.layer_mode,
                              primary=args.primary or "raster",
                              denoise=args.denoise or args.denoise_iterations is not None,
                              denoise_iterations=args.denoise_iterations or RenderSettings.denoise_iterations,
                              accumulate=args.temporal, temporal=args.temporal,
                              second_layer=args.second_layer, stereo=args.stereo,
                              warp_layers=args.warp_layers, quadtree_adapt=args.quadtree_adapt,
                              traversal=args.traversal, bvh_build=args.bvh_build, seed=args.seed,
                              dof_aperture=args.aperture, dof_focus=args.focus_distance, dof_samples=args.dof_samples,
                              msaa=args.msaa, ssaa=args.ssaa, tile_culling=args.tile_culling)
    inputs = {"scene": _file_identity(args.scene), "materials": _file_identity(args.materials),
              "settings": repr(settings)}
    if args.workers:
        return _capture_on_workers(args, aux, settings, inputs)
    with Renderer(args.scene, args.materials, backend=args.backend, settings=settings) as r:
        rig = rig_from_args(args, r.scene)
        pick = None
        if args.budget_ms is not None:
            from .budget import auto_config, describe_pick

            config, pick = auto_config(r, rig, args.budget_ms, progress=not args.quiet)
            r.set_materials(config)
            inputs["budget"] = pick["assignment"]  # what it picked is what the frames show
            if not args.quiet:
                print(describe_pick(pick))
        poses, overrides = _capture_poses(args, rig, r.scene)
        job = CaptureJob(rig, poses, args.eye, args.view, aux, Path(args.out), args.prefix, args.format, args.spp,
                         rig_overrides=overrides, cameras=bool(args.views))
        # --temporal carries each frame into the next: only a whole run in order gives the same frames
        with JobFolder(job, job_identity(job, **inputs), resume=not args.temporal,  # held to the end
                       overwrite=args.overwrite) as folder:
            summary = run_capture(r, job, progress=not args.quiet, folder=folder)
            if pick is not None:
                summary["budget"] = pick
            summary_path = write_summary(job, summary)
            if args.views:
                from .views import write_transforms

                write_transforms(job)
    _print_capture(args, summary, summary_path, r.scene.summary())
    return 0


def _capture_on_workers(args, aux, settings, inputs) -> int:
    """`rayvr capture --workers N`: the frames in chunks over N Ray workers."""
    from . import scene as scene_mod
    from .capture import CaptureJob, JobFolder, job_identity, write_summary
    from .cluster import Cluster, WorkerSpec, run_capture_distributed

    from .materials import load_config

    scene = scene_mod.load(args.scene)  # for the rig and the poses; each worker loads its own
    load_config(args.materials).assign(scene.material_names(), warn=False)  # a bad config fails here, once
    rig = rig_from_args(args, scene)
    poses, overrides = _capture_poses(args, rig, scene)
    job = CaptureJob(rig, poses, args.eye, args.view, aux, Path(args.out), args.prefix, args.format, args.spp,
                     rig_overrides=overrides, cameras=bool(args.views))
    spec = WorkerSpec(args.scene, args.materials, settings, args.backend)
    with JobFolder(job, job_identity(job, **inputs), overwrite=args.overwrite) as folder, \
            Cluster(args.workers, spec, args.address, _connect_timeout(args)) as cluster:
        cluster.ready()  # a worker that cannot start is one clear error, before any frame
        summary = run_capture_distributed(cluster, job, progress=not args.quiet, chunk=args.chunk,
                                          crash_file=os.environ.get("RAYVR_TEST_CRASH_ONCE"), folder=folder)
        summary_path = write_summary(job, summary)
        if args.views:
            from .views import write_transforms

            write_transforms(job)
    _print_capture(args, summary, summary_path, scene.summary())
    missing = summary["missing_frames"]
    if missing:
        shown = ", ".join(map(str, missing[:10])) + (", ..." if len(missing) > 10 else "")
        print(f"rayvr capture: error: {len(missing)} frame(s) missing after the run ({shown}); "
              f"rerun the same command to render only those", file=sys.stderr)
        return 1
    return 0


def print_graph(args) -> int:
    """`rayvr info SCENE --materials FILE --graph [dot]`: the compiled frame graph."""
    from .context import create_context
    from .frame import compile_graph
    from .renderer import Renderer, candidate_passes

    camera = camera_from_args(args)
    gl = create_context(args.backend)
    try:
        settings = settings_from_args(args, stereo=args.stereo, accumulate=args.spp > 1, denoise=args.denoise)
        with Renderer(args.scene, args.materials, gl=gl, settings=settings) as r:
            plan = r.plan(layers=2, view=args.view, camera=camera)
            graph = compile_graph(candidate_passes(plan), plan)  # passes are not built: nothing compiles
            print(graph.dot() if args.graph == "dot" else graph.describe(r.sizing(args.size, plan.layers, plan)), end="")
    finally:
        gl.release()
    if args.graph != "dot":
        print()
    return 0


def cmd_info(args) -> int:
    from .context import create_context

    if args.graph:
        return print_graph(args)
    gl = create_context(args.backend)
    try:
        info = gl.info()
    finally:
        gl.release()
    if args.scene is not None or args.materials:
        from . import materials, scene

        s = scene.load(args.scene)
        cfg = materials.load_config(args.materials)
        assigned = cfg.assign(s.material_names(), warn=False)
        info["scene"] = {"summary": s.summary(), "materials": [
            {"index": i, "name": m.name, "effect": a.effect, "rule": a.rule, "params": a.params}
            for i, (m, a) in enumerate(zip(s.materials, assigned))],
            "lights": [{"kind": l.kind, "source": l.source} for l in s.lights],
            "unmatched_config_keys": cfg.unmatched(s.material_names())}
    if args.json:
        print(json.dumps(info, indent=1, default=str))
        return 0
    print(f"backend   {info['backend']}")
    print(f"vendor    {info['vendor']}\nrenderer  {info['renderer']}\nversion   {info['version']}\nglsl      {info['glsl']}")
    print("limits")
    for k, v in info["limits"].items():
        print(f"  {k:40s} {v}")
    print("extensions rayvr uses")
    for k, v in info["extensions"].items():
        print(f"  {'yes' if v else 'no ':3s} {k}")
    if "scene" in info:
        print(info["scene"]["summary"])
        for m in info["scene"]["materials"]:
            print(f"  [{m['index']:3d}] {m['name']:24s} -> {m['effect']:12s} ({m['rule']})")
        for key in info["scene"]["unmatched_config_keys"]:
            print(f"  warning: config key {materials.short(repr(key))} matches no material")
    return 0


def add_connect_timeout_argument(p: argparse.ArgumentParser) -> None:
    from .cluster import DEFAULT_CONNECT_TIMEOUT_S

    p.add_argument("--connect-timeout", type=_number(0, 86400), metavar="SECONDS",
                   help=f"with --address: give up on a Ray cluster that does not answer within this time "
                        f"(default {DEFAULT_CONNECT_TIMEOUT_S:g} s)")


def _connect_timeout(args) -> float:
    from .cluster import DEFAULT_CONNECT_TIMEOUT_S

    return DEFAULT_CONNECT_TIMEOUT_S if args.connect_timeout is None else args.connect_timeout


def add_bvh_build_argument(p: argparse.ArgumentParser) -> None:
    """How the scene's BVH is built (capture, preview)."""
    p.add_argument("--bvh-build", choices=BUILDS, default="sah",
                   help="BVH build: sah (binned SAH, default) or sbvh (spatial splits: lower SAH cost, up to 30 %% "
                        "more triangle references, a longer build; accel/sbvh.py)")


def _split(text: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip())


def _among(text: str, what: str, allowed, unique: bool = False) -> tuple[str, ...]:
    """Comma-separated names, each in `allowed` (`unique`: repeats dropped)."""
    names = tuple(dict.fromkeys(_split(text))) if unique else _split(text)
    if not names or any(x not in allowed for x in names):
        raise argparse.ArgumentTypeError(f"{what} must be among {', '.join(allowed)}, got {text!r}")
    return names


def _builds(text: str) -> tuple[str, ...]:
    return _among(text, "BVH builds", BUILDS, unique=True)


def _traversal(text: str) -> tuple[str, str, str]:
    try:
        return parse_traversal(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _layouts(text: str) -> tuple[str, ...]:
    return _among(text, "BVH layouts", BVH_LAYOUTS)


def _names(text: str) -> tuple[str, ...]:
    names = _split(text)
    if not names:
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return names


def _sample_counts(text: str) -> tuple[int, ...]:
    from .cameras.sampling import SAMPLE_COUNTS

    try:
        counts = tuple(int(x) for x in text.split(","))
    except ValueError:
        counts = ()
    if not counts or any(n not in SAMPLE_COUNTS for n in counts):
        raise argparse.ArgumentTypeError(f"sub-ray counts must be among {', '.join(map(str, SAMPLE_COUNTS))}, "
                                         f"got {text!r}")
    return counts


def _budgets(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated milliseconds, got {text!r}") from None
    if not values or not all(np.isfinite(values)) or min(values) <= 0:
        raise argparse.ArgumentTypeError(f"budgets must be positive milliseconds, got {text!r}")
    return values


def cmd_bench(args) -> int:
    from .bench import run_area
    from .output import check_output_dir

    out = check_output_dir(args.out)  # before any measuring: results are written after it
    run_area(args, out, camera_from_args)
    print(f"results in {out}/{args.area}.json and {args.area}.md")
    return 0


def cmd_preview(args) -> int:
    from .preview import Preview

    rig_options = {"ipd": args.ipd, "camera": camera_from_args(args)}
    for key, attr in (("fov_y", "fov"), ("convergence", "convergence")):
        if getattr(args, attr) is not None:
            rig_options[key] = getattr(args, attr)
    look_at = (args.camera[:3], args.camera[3:]) if args.camera else None
    with Preview(args.scene, args.materials, size=args.size, vsync=not args.no_vsync, stereo=args.mode,
                 stereo_method=args.stereo,
                 view=args.view, res_scale=args.scale, rig_options=rig_options, look_at=look_at,
                 out_dir=args.out, path_file=args.record,
                 dof=(args.aperture, args.focus_distance, args.dof_samples), seed=args.seed, settings=settings_from_args(args)) as p:
        if args.budget_ms is not None:
            print(p.apply_budget(args.budget_ms))
        p.run(max_frames=args.frames)
    return 0


class OneLineErrors(argparse.ArgumentParser):
    """A usage error is one line, like every other rayvr error (argparse prints the whole usage
    first); exit status 2 as argparse's. Sub-commands get this class too."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} -h)\n")


def add_dof_arguments(p) -> None:
    """Thin-lens depth of field through screen-space rays (passes/dof.py), capture and preview."""
    p.add_argument("--aperture", type=_number(0, 1e6, lo_open=False), default=0.0,
                   help="depth of field: lens diameter in scene units (default 0: off; pinhole, stereo dual)")
    p.add_argument("--focus-distance", type=_number(0, 1e9), default=2.0,
                   help="depth of field: view depth in focus, scene units (default 2)")
    p.add_argument("--dof-samples", type=_count(1, 1024), default=16, help="depth of field: lens rays per pixel")


def build_parser() -> argparse.ArgumentParser:
    from .gpu_layout import TONEMAPPERS, VIEWS
    from .output import EXR_EXTRA, FORMATS
    from .readback import AUX_CHANNELS

    p = OneLineErrors(prog="rayvr", description="Hybrid raster + ray-traced stereo renderer for VR.")
    p.add_argument("-v", "--verbose", action="store_true", help="log what rayvr decides")
    sub = p.add_subparsers(dest="command", required=True)

    c = sub.add_parser("capture", help="render headless to PNG/NPY or EXR (default: the built-in scene, both eyes)")
    c.add_argument("scene", nargs="?", help="glTF/GLB, OBJ or PLY file (default: built-in room)")
    c.add_argument("--materials", help="material-ID config (TOML)")
    c.add_argument("--eye", choices=("both", "left", "right"), default="both")
    c.add_argument("--out", default="out", help="output folder (default ./out)")
    c.add_argument("--prefix", type=_prefix, default="frame", help="file name prefix (default 'frame')")
    c.add_argument("--view", choices=VIEWS, default="color", help="colour or a G-buffer debug view")
    c.add_argument("--aux", help=f"extra channels as .npy, comma-separated: {','.join(AUX_CHANNELS)}")
    c.add_argument("--format", choices=FORMATS, default="png",
                   help=f"exr: also the linear HDR colour as PREFIX_EYE.exr beside the PNG, and the float aux "
                        f"channels as .exr instead of .npy (integer ones stay .npy); needs {EXR_EXTRA}")
    seq = c.add_mutually_exclusive_group()
    seq.add_argument("--frames", type=FRAMES, help="N frames of a turntable orbit")
    seq.add_argument("--path", help="camera path file (JSON) to replay")
    n = c.add_argument_group("noise (accumulation and denoising)")
    n.add_argument("--spp", type=SPP, default=1,
                   help="samples per pixel: N frames' samples of the sampled effects accumulated into each image")
    n.add_argument("--denoise", action="store_true",
                   help="edge-aware a-trous denoiser on the pixels of the effects the config's `denoise` key "
                        "lists (default: every traced effect)")
    n.add_argument("--denoise-iterations", type=DENOISE_ITERATIONS, metavar="K",
                   help=f"a-trous iterations, 1..{MAX_DENOISE_ITERATIONS} (default 4; implies --denoise)")
    c.add_argument("--overwrite", action="store_true",
                   help="sequences: render every frame again, deleting the PREFIX_NNNN_* frames any job left in "
                        "--out (default: a rerun of the same job renders only the frames whose records do not "
                        "verify, and frames of another job are refused)")
    n.add_argument("--temporal", action="store_true",
                   help="camera paths: carry each frame's samples into the next by reprojection (pinhole)")
    seq.add_argument("--views", metavar="FILE|sphere:N|grid:NxM[:SPACING]",
                     help="multi-view capture: a views file (JSON poses/intrinsics, or a transforms.json) or N views "
                          "on a sphere around the scene / an NxM camera array; writes depth, per-view camera files "
                          "and transforms.json (NeRF / 3D Gaussian splatting layout)")
    c.add_argument("--workers", type=_count(1, 1024), help="render on N Ray workers, one per GPU (CPU processes "
                   "where there is none); needs pip install 'rayvr[cluster]'")
    c.add_argument("--address", help="with --workers: an existing Ray cluster, 'auto' or HOST:PORT "
                   "(default: start a local one)")
    add_connect_timeout_argument(c)
    c.add_argument("--chunk", type=_count(1, MAX_FRAMES), help="with --workers: frames per task (default: about "
                   "4 tasks per worker, at most 32 frames)")
    c.add_argument("--timings", action="store_true", help="print GPU ms per pass")
    c.add_argument("--seed", type=SEED, default=0, help="random sequence of the sampled effects (default 0): "
                   "the same seed gives the same image")
    c.add_argument("--budget-ms", type=BUDGET_MS, help="pick effects per material to fit this GPU frame time "
                   "(measured on this device against a reference; overrides --materials' effects)")
    c.add_argument("--exposure", type=_number(0, MAX_EXPOSURE), default=1.0,
                   help="linear scale before tonemapping (default 1)")
    c.add_argument("--tonemapper", choices=TONEMAPPERS, default="aces")
    c.add_argument("--layer-mode", choices=("auto", "vertex", "geometry", "multiview", "passes"), default="auto",
                   help="how the stereo G-buffer reaches both layers")
    c.add_argument("--traversal", type=_traversal, default=DEFAULT_TRAVERSAL, metavar="LAYOUTS",
                   help="BVH node layout of the traced rays: one for all (bvh2, bvh4, bvh8) or per ray kind, "
                        "e.g. primary=bvh8,shadow=bvh4,reflect=bvh2; kinds not named keep the default "
                        "primary=bvh4,shadow=bvh2,reflect=bvh4 (the fastest on the H200; bvh2 is the reference)")
    add_bvh_build_argument(c)
    c.add_argument("--primary", choices=("raster", "rays"), default=None,
                   help="primary visibility: the raster G-buffer pass, or camera rays through the BVH (default: "
                        "raster, or rays where --msaa or the camera model needs them)")
    c.add_argument("--second-layer", choices=("rays", "peel"), default="rays",
                   help="how the second depth layer (ssr layers = 2) is made: primary rays continued through the "
                        "BVH, or depth peeling in the raster (rayvr bench ssrt times both)")
    add_dof_arguments(c)
    c.add_argument("--quadtree-adapt", type=_number(0, 1e6, lo_open=False), default=0.0,
                   help="distance-adaptive quadtree thresholds (Widmer et al. §6): gamma_dist and the normal "
                        "angle grow by 1 + this x the node's view depth (scene units); 0 = off")
    c.add_argument("--backend", choices=("egl", "osmesa"), help="headless GL backend (default: egl, then osmesa)")
    add_stereo_argument(c, warp_layers=True)

    c.add_argument("-q", "--quiet", action="store_true")
    add_rig_arguments(c)
    add_camera_arguments(c)
    c.set_defaults(func=cmd_capture)

    i = sub.add_parser("info", help="GL vendor, renderer, version, limits, extensions; a scene's material effects")
    i.add_argument("scene", nargs="?", help="also list this scene's materials and their effects")
    i.add_argument("--materials", help="material-ID config to apply to the scene")
    i.add_argument("--backend", choices=("egl", "osmesa"))
    i.add_argument("--json", action="store_true")
    i.add_argument("--graph", nargs="?", const="text", choices=("text", "dot"),
                   help="print the compiled frame graph (passes in order, why each runs, resources); "
                        "'dot' for Graphviz")
    i.add_argument("--size", type=_size, default="1440x1600", help="per-eye size the --graph resources are sized for")
    i.add_argument("--view", choices=VIEWS, default="color", help="the view --graph is compiled for")
    i.add_argument("--primary", choices=("raster", "rays"), default=None,
                   help="primary visibility for --graph (default: as capture chooses)")
    add_stereo_argument(i)
    i.add_argument("--spp", type=SPP, default=1, help="the --graph of a capture with this many samples a pixel")
    i.add_argument("--denoise", action="store_true", help="the --graph with the denoiser")
    add_camera_arguments(i)
    i.set_defaults(func=cmd_info)

    from .bench import AREAS, areas_help

    b = sub.add_parser("bench", help="GPU benchmarks (run on a real GPU)")
    b.add_argument("area", choices=tuple(AREAS), help=areas_help())
    b.add_argument("--budget-ms", type=_budgets, default=[4.0, 8.0], help="frame budgets for 'budget' (default 4,8)")
    b.add_argument("--out", default="bench/results", help="folder for JSON/markdown results")
    b.add_argument("--size", type=_size, default=(1440, 1600), help="per-eye size (default 1440x1600)")
    b.add_argument("--scenes", default="default,sponza", help="comma-separated: default, sponza")
    b.add_argument("--repeat", type=REPEAT, default=50,
                   help="timed frames per measurement (default 50; rays and primary time half of it, photon, "
                        "gi, tradeoff and budget a fifth, at least 1)")
    b.add_argument("--quick", action="store_true", help="tiny sizes and few frames (CI smoke test)")
    b.add_argument("--layouts", type=_layouts, default=tuple(BVH_LAYOUTS),
                   help=f"rays: BVH node layouts to measure, comma-separated (default {','.join(BVH_LAYOUTS)}; "
                        f"bvh2, the reference, always runs)")
    b.add_argument("--bvh-build", type=_builds, metavar="BUILDS",
                   help="rays, primary: BVH builds to measure, comma-separated among sah,sbvh (default sah; the "
                        "first is the reference); bvh: the builds to compare (default sah,sbvh)")
    b.add_argument("--no-tiles", action="store_true", help="rays, primary: leave out the tile frustum culling variant")
    b.add_argument("--workers", type=_worker_counts, help="tradeoff/budget: spread the variants over N Ray workers; "
                   "workers: the worker counts to time (default 1,2); needs pip install 'rayvr[cluster]'")
    b.add_argument("--address", help="with --workers: an existing Ray cluster, 'auto' or HOST:PORT")
    add_connect_timeout_argument(b)
    b.add_argument("--frames", type=FRAMES, default=64, help="workers: frames of the capture path (default 64)")
    b.add_argument("--backend", choices=("egl", "osmesa"))
    b.add_argument("--fov", type=FOV, help="primary: vertical field of view of the --camera-model row")
    b.add_argument("--configs", type=_names,
                   help="primary: the bench views' rows to measure, comma-separated, alone (default: the paper's "
                        "Table 5 rows at 2160x1200, then raster_gbuffer, pinhole at --size; among raster_gbuffer, "
                        "pinhole, distorted, distorted_chromatic, foveated, wide_210x130, dof_0.5m, dof_0.25m, "
                        "dof_0.1m); gi: the parts to measure (default all: photon, reuse, path)")
    b.add_argument("--reference-spp", type=_count(16, 1 << 16),
                   help="gi: samples per pixel of the path reference (default 1024; --quick 64)")
    b.add_argument("--reference-photons", type=_count(256, 1 << 22),
                   help="gi: photon paths of the photon tables' reference (default 4194304; --quick 32768)")
    b.add_argument("--counts", type=_sample_counts,
                   help="primary: sub-rays per sample of the bench views' rows, comma-separated (default 1,4,16)")
    add_camera_arguments(b, msaa_default=None)
    b.set_defaults(func=cmd_bench)

    v = sub.add_parser("preview", help="desktop stereo preview window (glfw); H in the window lists the keys")
    v.add_argument("scene", nargs="?", help="glTF/GLB, OBJ or PLY file (default: built-in room)")
    v.add_argument("--materials", help="material-ID config (TOML), reloaded when the file changes")
    v.add_argument("--size", type=_size, default=(1280, 720), help="window size WxH (default 1280x720)")
    v.add_argument("--mode", choices=("side-by-side", "cross-eyed", "anaglyph", "left", "right"),
                   default="side-by-side", help="stereo mode at start (Tab cycles)")
    v.add_argument("--view", choices=VIEWS, default="color", help="colour or a debug view at start (V cycles)")
    v.add_argument("--scale", type=float, help="resolution scale (default 1, 0.5 on a CPU rasterizer)")
    v.add_argument("--no-vsync", action="store_true", help="start with vsync off (Y toggles)")
    v.add_argument("--camera", type=_floats(6), metavar="EX,EY,EZ,TX,TY,TZ", help="start eye position and target")
    v.add_argument("--fov", type=FOV, help="vertical field of view in degrees")
    v.add_argument("--ipd", type=IPD, default=0.064, help="interpupillary distance (default 0.064)")
    v.add_argument("--convergence", type=DISTANCE, help="zero-parallax distance (default: parallel eyes)")
    v.add_argument("--out", default="shots", help="screenshot folder (default ./shots)")
    v.add_argument("--record", default="camera_path.json", help="camera path file P writes")
    v.add_argument("--seed", type=SEED, default=0, help="random sequence of the sampled effects (default 0)")
    v.add_argument("--frames", type=FRAMES, help="close after N frames (smoke tests)")
    v.add_argument("--budget-ms", type=BUDGET_MS, help="pick effects per material to fit this GPU frame time at start")
    add_stereo_argument(v, " at start (B cycles)")
    add_dof_arguments(v)
    add_camera_arguments(v)
    add_bvh_build_argument(v)
    v.set_defaults(func=cmd_preview)
    return p


EXIT_INTERRUPTED = 130  # 128 + SIGINT, what a shell reports for a process Ctrl-C ended
EXIT_TERMINATED = 128 + signal.SIGTERM


@contextlib.contextmanager
def sigterm_as_interrupt():
    """While the command runs, SIGTERM (kill, a job scheduler) raises KeyboardInterrupt where the
    command is, so that it ends as Ctrl-C does: temporary files, and an output folder it made and
    left empty, are removed on the way. Yields a list that holds the signal once it came."""
    received = []

    def on_sigterm(signum, frame):
        received.append(signum)
        raise KeyboardInterrupt("terminated")

    with handling(signal.SIGTERM, on_sigterm):
        yield received


def main(argv=None) -> int:
    code = run_command(argv)
    from .cluster import connect_left_behind
    if argv is None and connect_left_behind():  # a process of its own: no exit handler may wait on Ray
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def run_command(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="rayvr: %(message)s")
    from .context import ContextError
    from .materials import ConfigError
    from .output import OutputError
    from .scene import SceneError
    from .shaders import ShaderError
    from .cluster import ClusterError

    with sigterm_as_interrupt() as sigterm:
        try:
            return args.func(args)
        except (ContextError, ConfigError, SceneError, OutputError, ShaderError, ClusterError, MissingExtraError,
                ValueError) as exc:
            print(f"rayvr {args.command}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: one line, the shell's status for the signal
            print(f"rayvr {args.command}: {str(exc) or 'interrupted'}", file=sys.stderr)
            return EXIT_TERMINATED if sigterm else EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
