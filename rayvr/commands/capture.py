"""`rayvr capture`: render headless to PNG/NPY or EXR (docs/capture.md: the pipeline and its flags)."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from ..util.extras import require
from . import args as shared

COMMAND = "capture"


def prefix(text: str) -> str:
    import argparse

    from ..util.output import check_file_prefix

    try:
        return check_file_prefix(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_parser(sub) -> None:
    from ..gl.gpu_layout import VIEWS
    from ..util.output import EXR_EXTRA, FORMATS
    from ..frame.readback import AUX_CHANNELS
    from ..app.writers import DEFAULT_PNG_COMPRESSION, MAX_DEFAULT_WRITERS, PNG_COMPRESSION_LEVELS

    c = sub.add_parser("capture", help="render headless to PNG/NPY or EXR (default: the built-in scene, both eyes)")
    c.add_argument("scene", nargs="?", help="glTF/GLB, OBJ or PLY file (default: built-in room)")
    c.add_argument("--materials", help="material-ID config (TOML); its [render] table sets render options (the "
                   "flags override it)")
    c.add_argument("--eye", choices=("both", "left", "right"), default="both")
    c.add_argument("--out", default="out", help="output folder (default ./out)")
    c.add_argument("--prefix", type=prefix, default="frame", help="file name prefix (default 'frame')")
    c.add_argument("--view", choices=VIEWS, default="color", help="colour or a G-buffer debug view")
    c.add_argument("--aux", help=f"extra channels as .npy, comma-separated: {','.join(AUX_CHANNELS)}, distance "
                                 f"(from the eye along each pixel's ray: depth's other convention), flow (a "
                                 f"sequence's forward and backward optical flow in pixels; a static scene, a pinhole "
                                 f"camera)")
    c.add_argument("--format", choices=FORMATS, default="png",
                   help=f"exr: also the linear HDR colour as PREFIX_EYE.exr beside the PNG, and the float aux "
                        f"channels as .exr instead of .npy (integer ones stay .npy); needs {EXR_EXTRA}. npy: the "
                        f"colour as raw uint8 RGB .npy instead of PNG (no encoding: as fast as the disk allows)")
    c.add_argument("--png-compression", type=shared.count(PNG_COMPRESSION_LEVELS[0], PNG_COMPRESSION_LEVELS[-1]),
                   default=DEFAULT_PNG_COMPRESSION, metavar="0..9",
                   help=f"zlib level of the PNGs: 0 stores (largest, fastest), 9 compresses hardest (slowest); "
                        f"every level is lossless (default {DEFAULT_PNG_COMPRESSION}: several times faster than 6, "
                        f"files as small on shaded frames, up to 1.8x larger on flat ones)")
    c.add_argument("--writers", type=shared.count(1, 256), metavar="N",
                   help=f"threads that encode and write frames while the GPU renders the next ones (default: "
                        f"one per core, at most {MAX_DEFAULT_WRITERS}; 1: each frame written in turn)")
    seq = c.add_mutually_exclusive_group()
    seq.add_argument("--frames", type=shared.FRAMES, help="N frames of a turntable orbit")
    seq.add_argument("--path", help="camera path file (JSON) to replay")
    seq.add_argument("--views", metavar="FILE|sphere:N|grid:NxM[:SPACING]",
                     help="multi-view capture: a views file (JSON poses/intrinsics, or a transforms.json) or N views "
                          "on a sphere around the scene / an NxM camera array; writes depth, per-view camera files "
                          "and transforms.json (NeRF / 3D Gaussian splatting layout)")
    c.add_argument("--spp", type=shared.SPP, default=1,
                   help="samples per pixel: N frames' samples of the sampled effects accumulated into each image")
    c.add_argument("--overwrite", action="store_true",
                   help="sequences: render every frame again, deleting the PREFIX_NNNN_* frames any job left in "
                        "--out (default: a rerun of the same job renders only the frames whose records do not "
                        "verify, and frames of another job are refused)")
    c.add_argument("--workers", type=shared.count(1, 1024), help="render on N Ray workers, one per GPU (CPU "
                   "processes where there is none); needs pip install 'rayvr[cluster]'")
    c.add_argument("--address", help="with --workers: an existing Ray cluster, 'auto' or HOST:PORT "
                   "(default: start a local one)")
    shared.add_connect_timeout_argument(c)
    c.add_argument("--chunk", type=shared.count(1, shared.MAX_FRAMES), help="with --workers: frames per task "
                   "(default: about 4 tasks per worker, at most 32 frames)")
    c.add_argument("--timings", action="store_true", help="print GPU ms per pass")
    shared.add_budget_arguments(c, "pick effects per material to fit this GPU frame time (measured on this device "
                                   "against a reference; overrides --materials' effects); the pick is printed as a "
                                   "config to save")
    c.add_argument("--backend", choices=("egl", "osmesa"), help="headless GL backend (default: egl, then osmesa)")
    shared.add_device_argument(c)
    c.add_argument("-q", "--quiet", action="store_true")
    shared.add_rig_arguments(c)
    shared.add_render_arguments(c, COMMAND)
    shared.add_capture_default_arguments(c)
    c.set_defaults(func=cmd_capture)


def file_identity(path) -> dict | None:
    """A file's identity for resuming a capture: its path, size and modification time; a file rayvr
    ships (rayvr/assets/, e.g. the built-in room's default config) by its name and content, so that
    a capture of another checkout or clone of the same rayvr resumes."""
    import hashlib

    from ..scene.loader import ASSETS_DIR

    if path is None:
        return None
    try:
        resolved = Path(path).resolve()
        st = resolved.stat()
        if resolved.parent == ASSETS_DIR:
            return {"shipped": resolved.name, "sha256": hashlib.sha256(resolved.read_bytes()).hexdigest()}
    except OSError:  # the loader says what is wrong with it
        return {"path": str(path)}
    return {"path": str(resolved), "bytes": st.st_size, "mtime_ns": st.st_mtime_ns}


def capture_poses(args, rig, scene):
    """(poses, per-frame rig overrides or None) of --views, --path, --frames or the rig's pose."""
    from ..app.capture import poses_for

    if args.views:
        from ..app.views import views_for

        return views_for(args.views, scene, rig)
    return poses_for(rig, scene, args.frames, args.path), None


def print_capture(args, summary, summary_path, scene_summary) -> None:
    if not args.quiet:
        print(scene_summary)
        if summary["files"] or not summary.get("skipped"):
            print(f"wrote {len(summary['files'])} files to {args.out}/ ({summary['frames']} frame(s), {args.eye} eye(s))")
        else:  # a resume that found every frame written
            print(f"nothing to write: {args.out}/ holds all {summary['frames']} frame(s) ({args.eye} eye(s)) already")
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
    from ..app.capture import CaptureJob, JobFolder, job_identity, run_capture, write_summary
    from ..scene.materials import load_config
    from ..util.output import check_output_dir
    from ..renderer import Renderer, RenderSettings

    config = load_config(args.materials)  # its [render] table, under the flags
    given = shared.render_values(args, COMMAND, config)
    grid = shared.budget_grid(args, given, frame_knobs=("stereo", "spp", "denoise", "msaa"),
                              defaults=shared.CAPTURE_DEFAULTS)
    given = shared.with_capture_defaults(given)  # denoised unless --no-denoise (or the config) says not
    settings = RenderSettings(**given)  # --temporal implies accumulate, --denoise-iterations --denoise
    if args.budget_ms is not None:
        require("flip_evaluator", "--budget-ms")  # it predicts image error with FLIP, before any work
    if not args.workers and (args.address or args.chunk or args.connect_timeout is not None):
        raise ValueError("--address, --connect-timeout and --chunk go with --workers N")
    if args.format == "npy" and args.views:
        raise ValueError("--views writes a transforms.json for NeRF / 3D Gaussian splatting tools, which read "
                         "images: use --format png or exr with --views")
    if args.workers:
        from ..app.cluster import require_ray

        require_ray()  # the optional extra, before any work
        if args.budget_ms is not None:
            raise ValueError("--budget-ms picks effects on this machine's GPU; run it without --workers and "
                             "pass the config it reports with --materials")
        if settings.temporal:
            raise ValueError("--temporal carries each frame's samples into the next, so its frames render in "
                             "order in one process; leave out --workers")
    check_output_dir(args.out)  # fail before any rendering work; the folder is made with the first file
    if args.quiet:
        from ..accel.sbvh import set_progress_bars

        set_progress_bars(False)  # the BVH build's bar, which the Renderer starts deep inside a frame
    if args.format == "exr":
        from ..util.output import openexr

        openexr()  # the optional package, before any work
    aux = tuple(a for a in (args.aux or "").split(",") if a)
    if settings.stereo == "warp" and args.format == "exr" and args.eye == "both" and args.view == "color":
        raise ValueError("--format exr writes the linear HDR colour, which --stereo warp does not make "
                         "(it warps the displayed colour): use --stereo dual or reuse")
    if args.views and "depth" not in aux:
        aux += ("depth",)  # a multi-view capture writes depth beside every view
    inputs = {"scene": file_identity(args.scene), "materials": file_identity(args.materials),
              "settings": settings.to_dict()}
    if args.workers:
        return capture_on_workers(args, aux, settings, inputs, given)
    with Renderer(args.scene, config, backend=args.backend, settings=settings) as r:
        rig = shared.rig_from_args(args, r.scene, shared.camera_from_args(args, settings, given))
        pick = None
        if args.budget_ms is not None:
            from ..quality.budget import describe_pick, pick_toml
            from ..quality.frame_budget import auto_config

            if r.gl.is_software and not args.quiet:
                print(f"note: {r.gl.info()['renderer']} is a software rasterizer: the budget's GPU timings do not "
                      f"measure a GPU here, so its pick (and whether it fits {args.budget_ms:.2f} ms) says nothing "
                      f"about a headset's GPU; it takes a while on a CPU")
            config, pick = auto_config(r, rig, args.budget_ms, progress=not args.quiet, grid=grid)
            r.set_materials(config)
            if grid:  # the frame-wide knobs it picked: render options and samples per pixel
                settings = r.settings = RenderSettings(**{**given, **pick["knobs"].render_table()})
                args.spp = pick["knobs"].spp
                inputs["settings"] = settings.to_dict()
            inputs["budget"] = pick["assignment"]  # what it picked is what the frames show
            if not args.quiet:
                print(describe_pick(pick))
                print(pick_toml(r.scene, pick, config, rig.size), end="")
            pick = {**pick, "knobs": pick["knobs"].label} if grid else pick
        poses, overrides = capture_poses(args, rig, r.scene)
        job = CaptureJob(rig, poses, args.eye, args.view, aux, Path(args.out), args.prefix, args.format, args.spp,
                         rig_overrides=overrides, cameras=bool(args.views), png_compression=args.png_compression,
                         writers=args.writers)
        # --temporal carries each frame into the next: only a whole run in order gives the same frames
        with JobFolder(job, job_identity(job, **inputs), resume=not settings.temporal,  # held to the end
                       overwrite=args.overwrite) as folder:
            summary = run_capture(r, job, progress=not args.quiet, folder=folder)
            if pick is not None:
                summary["budget"] = pick
            summary_path = write_summary(job, summary)  # (run_capture wrote transforms.json)
    print_capture(args, summary, summary_path, r.scene.summary())
    return 0


def capture_on_workers(args, aux, settings, inputs, given) -> int:
    """`rayvr capture --workers N`: the frames in chunks over N Ray workers."""
    from ..scene import loader as scene_mod
    from ..app.capture import CaptureJob, JobFolder, job_identity, write_summary
    from ..app.cluster import Cluster, WorkerSpec, run_capture_distributed
    from ..app.writers import writers_per_worker
    from ..scene.materials import load_config

    scene = scene_mod.load(args.scene)  # for the rig and the poses; each worker loads its own
    load_config(args.materials).assign(scene.material_names(), warn=False)  # a bad config fails here, once
    rig = shared.rig_from_args(args, scene, shared.camera_from_args(args, settings, given))
    poses, overrides = capture_poses(args, rig, scene)
    job = CaptureJob(rig, poses, args.eye, args.view, aux, Path(args.out), args.prefix, args.format, args.spp,
                     rig_overrides=overrides, cameras=bool(args.views), png_compression=args.png_compression,
                     writers=writers_per_worker(args.writers, args.workers, local=args.address is None))
    # each worker writes its frames through its own pool
    spec = WorkerSpec(args.scene, args.materials, settings, args.backend)
    with JobFolder(job, job_identity(job, **inputs), overwrite=args.overwrite) as folder, \
            Cluster(args.workers, spec, args.address, shared.connect_timeout(args)) as cluster:
        cluster.ready()  # a worker that cannot start is one clear error, before any frame
        summary = run_capture_distributed(cluster, job, progress=not args.quiet, chunk=args.chunk,
                                          crash_file=os.environ.get("RAYVR_TEST_CRASH_ONCE"), folder=folder)
        summary_path = write_summary(job, summary)
        if job.writes_transforms:  # the workers render and write the frames; the listing is written here
            from ..app.views import write_transforms

            write_transforms(job, scene.material_names())
    print_capture(args, summary, summary_path, scene.summary())
    missing = summary["missing_frames"]
    if missing:
        shown = ", ".join(map(str, missing[:10])) + (", ..." if len(missing) > 10 else "")
        print(f"rayvr capture: error: {len(missing)} frame(s) missing after the run ({shown}); "
              f"rerun the same command to render only those", file=sys.stderr)
        return 1
    return 0
