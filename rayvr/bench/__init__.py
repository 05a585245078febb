"""The benchmarks (`rayvr bench AREA`): one table, AREAS, from which the command line takes its
choices, their help and the run of each. An area's module is imported only when it runs.

The benchmarks sit above the renderer (docs/architecture.md, "Layers"): they import the product,
never the reverse; the CLI reaches them through this table alone.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

QUICK_SCENES = ("default",)  # --quick: the built-in room only


@dataclass(frozen=True)
class Area:
    help: str
    run: Callable  # run(args, out, camera_from_args): measures, writes out/<area>.json and .md
    needs: tuple = ()  # optional modules it measures with (extras.EXTRAS), required before any work
    workers: str = ""  # --workers: "one" (a count that spreads its variants), "list" (the counts it times)


def _scenes(args) -> tuple[str, ...]:
    return QUICK_SCENES if args.quick else tuple(args.scenes.split(","))


def share(repeat: int, parts: int) -> int:
    """A bench's timed frames per variant from --repeat when it times `parts` things per row: at least one."""
    return max(1, repeat // parts)


def checked_configs(area: str, names, allowed) -> tuple[str, ...] | None:
    """`--configs` of bench `area`, checked against its `allowed` names (None: not given)."""
    if names is not None and any(x not in allowed for x in names):
        raise ValueError(f"bench {area} --configs must be among {', '.join(allowed)}, got {','.join(names)!r}")
    return names


def _connect_timeout(args) -> float:
    from ..app.cluster import DEFAULT_CONNECT_TIMEOUT_S

    return DEFAULT_CONNECT_TIMEOUT_S if args.connect_timeout is None else args.connect_timeout


def _gbuffer(args, out, camera_from_args):
    from . import gbuffer

    gbuffer.run(out, size=(64, 64) if args.quick else args.size, scenes=_scenes(args),
                repeat=3 if args.quick else args.repeat, warmup=1 if args.quick else 5, backend=args.backend)


def wavefront_variants(args) -> dict | None:
    """{name: RenderSettings fields}: every pair of the --ray-order and --persistent values given
    (bench rays, vr: grid axes); None when neither is."""
    orders, modes = getattr(args, "ray_orders", None), getattr(args, "persistent_modes", None)
    if orders is None and modes is None:
        return None
    return {f"ray_order={o},persistent={m}": {"ray_order": o, "persistent": m}
            for o in orders or ("none",) for m in modes or ("off",)}


def _rays(args, out, camera_from_args):
    from . import rays

    rays.run(out, size=(64, 48) if args.quick else args.size, scenes=_scenes(args),
             repeat=2 if args.quick else share(args.repeat, 2), warmup=1 if args.quick else 3, backend=args.backend,
             layouts=args.layouts, tiles=not args.no_tiles, builds=args.bvh_build or ("sah",),
             kinds=checked_configs("rays", args.configs, rays.RAY_KINDS), wavefront=wavefront_variants(args))


def _bvh(args, out, camera_from_args):
    from . import bvh

    bvh.run(out, size=(64, 48) if args.quick else args.size, scenes=_scenes(args),
            builds=args.bvh_build or ("sah", "sbvh"), samples=256 if args.quick else 4096)


def _primary(args, out, camera_from_args):
    from ..frame.cameras import DEFAULT_CAMERA_MODEL
    from . import primary

    quick = args.quick
    # A --camera-model / --camera-param / --fov given: that camera (and the raster reference) only;
    # any subset (that, --configs, --counts, --msaa): the bench views' rows alone, not Table 5's.
    custom = args.camera_model != DEFAULT_CAMERA_MODEL or args.camera_param or args.fov is not None
    subset = custom or args.configs or args.counts or args.msaa
    counts = args.counts or ((args.msaa,) if args.msaa else (1, 4) if quick else None)
    primary.run(out, size=(32, 24) if quick else args.size, scenes=_scenes(args),
                repeat=2 if quick else share(args.repeat, 2), warmup=1 if quick else 3, counts=counts,
                ssaa=(args.msaa,) if args.ssaa and args.msaa else () if quick else (4,),
                custom=(camera_from_args(args), args.fov) if custom else None, backend=args.backend,
                configs=checked_configs("primary", args.configs, primary.CONFIGS),
                suites=("views",) if subset else primary.SUITES,
                table5_size=(24, 16) if quick else primary.TABLE5_SIZE, tiles=not args.no_tiles,
                builds=args.bvh_build or ("sah",),
                frame_culling={None: (None,), True: (False, True), False: (False,)}[args.tile_culling])


def _peers(args, out, camera_from_args):
    from . import peers

    peers.run(out, size=(64, 36) if args.quick else (1280, 720), scenes=_scenes(args),
              frames=5 if args.quick else args.repeat * 4, backend=args.backend)


def _ssrt(args, out, camera_from_args):
    from . import ssrt

    ssrt.run(out, size=(64, 48) if args.quick else args.size, scenes=_scenes(args),
             repeat=2 if args.quick else args.repeat, backend=args.backend, quick=args.quick)


def _photon(args, out, camera_from_args):
    from . import photon

    photon.run(out, size=(32, 24) if args.quick else args.size, scenes=_scenes(args),
               repeat=1 if args.quick else share(args.repeat, 5), quick=args.quick, backend=args.backend)


def _gi(args, out, camera_from_args):
    from . import gi

    gi.run(out, size=(32, 24) if args.quick else args.size, scenes=_scenes(args),
           repeat=1 if args.quick else share(args.repeat, 5), warmup=1 if args.quick else 3, quick=args.quick,
           parts=checked_configs("gi", args.configs, gi.PARTS) or gi.PARTS, reference_spp=args.reference_spp,
           reference_photons=args.reference_photons, backend=args.backend, wavefront=wavefront_variants(args))


def _stereo(args, out, camera_from_args):
    from . import stereo

    stereo.run(out, size=(64, 48) if args.quick else args.size, scenes=_scenes(args),
               repeat=2 if args.quick else args.repeat, backend=args.backend)


def _sweep_arguments(args) -> dict:
    from .scenes import shipped_config

    return dict(size=(32, 24) if args.quick else args.size, scenes=_scenes(args),
                repeat=1 if args.quick else share(args.repeat, 5), base_config=shipped_config,
                backend=args.backend, workers=args.workers, address=args.address,
                connect_timeout=_connect_timeout(args), reference_spp=args.reference_spp)


def _tradeoff(args, out, camera_from_args):
    from . import tradeoff

    tradeoff.run(out, quick=args.quick, knobs=args.knobs, **_sweep_arguments(args), **_views(args, quick_poses=0))


def _budget(args, out, camera_from_args):
    from ..quality.frame_knobs import parse_grid
    from ..quality.rungs import budget_rungs
    from . import tradeoff

    budgets = _budgets(args) or tradeoff.BUDGETS_MS
    tradeoff.run_budget(out, budgets=tuple(budgets), quick=args.quick, grid=parse_grid(args.frame_knobs),
                        rungs=budget_rungs(args.rung_params), **_sweep_arguments(args), **_views(args))


def _budgets(args) -> list:
    """--budget-ms, or --budget-hz as frame times; [] without either."""
    from ..quality.frame_knobs import budget_ms_of

    return args.budget_ms or [budget_ms_of(hz) for hz in args.budget_hz or ()]


def _views(args, quick_poses: int = 1) -> dict:
    """tradeoff and budget: the head poses beside the fixed view (--poses; with --quick
    `quick_poses`: CI's budget run takes one, its tradeoff run none, to stay short), or the views
    --only-views names."""
    from .tradeoff import SWEEP_POSES

    if args.only_views is not None:
        if args.poses is not None:
            raise ValueError("give --only-views (the views by name) or --poses (the fixed view and that many head "
                             "poses), not both")
        poses = 1 + max((int(v.split()[1]) for v in args.only_views if v != "fixed"), default=-1)
        return {"poses": poses, "pose_seed": args.pose_seed, "views": args.only_views}
    return {"poses": args.poses if args.poses is not None else (quick_poses if args.quick else SWEEP_POSES),
            "pose_seed": args.pose_seed}


def _vr(args, out, camera_from_args):
    from .. import settings as settings_mod
    from ..util.extras import require
    from . import vr

    quick = vr.QUICK if args.quick else {}
    budgets = _budgets(args) or (vr.BUDGET_MS,)
    if len(budgets) != 1:
        raise ValueError(f"bench vr --budget-ms takes one budget (its budget config), got {len(budgets)}")
    configs = args.configs or quick.get("configs", vr.DEFAULT_CONFIGS)
    if "budget" in configs:
        require("flip_evaluator", "bench vr --configs budget")  # the pick predicts image error with FLIP
    # the render flags given (--tile-culling, --tile-lists, --ssaa) are one variant of every row; --msaa: the counts
    fields = {k: v for k, v in settings_mod.given_by_args(args, "bench").items() if k != "msaa"}
    given = ",".join(f"{k}={v}" for k, v in fields.items())
    variants = {given: fields} if fields else None
    wave = wavefront_variants(args)  # --ray-order, --persistent: a variant per pair, with those flags
    if wave is not None:
        variants = {",".join(filter(None, (given, name))): {**fields, **w} for name, w in wave.items()}
    named = getattr(args, "variants", None)  # --variants: each on top of the above (or of the flags)
    if named:
        base = variants or {given: fields}
        variants = {",".join(filter(None, (b, name))): {**bf, **v} for b, bf in base.items() for name, v in named.items()}
    vr.run(out, size=quick.get("size", args.size), scenes=_scenes(args),
           poses=args.poses if args.poses is not None else quick.get("poses", vr.POSES), pose_seed=args.pose_seed,
           cameras=args.cameras or quick.get("cameras", vr.CAMERAS),
           counts=args.counts or ((args.msaa,) if args.msaa else quick.get("counts", vr.COUNTS)), configs=configs,
           variants=variants, budget_ms=budgets[0], repeat=2 if args.quick else share(args.repeat, 5),
           warmup=1 if args.quick else 3, quick=args.quick, backend=args.backend)


def _lights(args, out, camera_from_args):
    from . import lights

    lights.run(out, size=(32, 24) if args.quick else args.size, scenes=_scenes(args),
               poses=1 if args.quick else (lights.POSES if args.poses is None else args.poses),
               repeat=2 if args.quick else share(args.repeat, 5), frames=2 if args.quick else 4,
               reference_frames=2 if args.quick else 8, backend=args.backend, pose_seed=args.pose_seed)


def _motion(args, out, camera_from_args):
    from . import motion

    motion.run(out, size=(32, 24) if args.quick else args.size, scenes=_scenes(args),
               seconds=0.03 if args.quick else motion.SECONDS, reference_spp=4 if args.quick else motion.REFERENCE_SPP,
               pose_seed=args.pose_seed, backend=args.backend)


def _crosscheck(args, out, camera_from_args):
    from . import mitsuba_ref

    mitsuba_ref.run(out, quick=args.quick)


def _workers(args, out, camera_from_args):
    from . import workers
    from .scenes import shipped_config

    workers.run(out, size=(32, 24) if args.quick else args.size, scenes=_scenes(args),
                frames=8 if args.quick else args.frames, workers=tuple(args.workers_list or [1, 2]),
                address=args.address, backend=args.backend, base_config=shipped_config,
                connect_timeout=_connect_timeout(args))


FLIP = ("flip_evaluator",)

AREAS: dict[str, Area] = {
    "gbuffer": Area("layered stereo vs mono G-buffer ms", _gbuffer),
    "rays": Area("rays/s vs Embree and the hybrid frame", _rays),
    "bvh": Area("the BVH builds (sah, sbvh) on the host: build s, references, SAH cost, node visits and triangle "
                "tests per ray kind (no GPU)", _bvh),
    "primary": Area("ray-cast primary visibility per camera model and sub-rays per sample (ms per pass, sub-rays/s) "
                    "against the raster G-buffer", _primary),
    "ssrt": Area("quadtree screen-space tracing vs the DDA baseline", _ssrt, FLIP),
    "photon": Area("the photon-mapping paper's tables (kd-tree vs hash grid, heap vs no heap: ms per pass, FLIP)",
                   _photon, FLIP),
    "gi": Area("the global illumination figures (the photon tables over 128²-512² x 0.02-0.2 m, Table 5 "
               "dual vs reuse, path at 1/4/16 spp with and without the denoiser; targets met or missed)", _gi, FLIP),
    "stereo": Area("the stereo modes dual, warp, reuse (ms per pass, FLIP against dual, holes)", _stereo, FLIP),
    "lights": Area("light picks by power (--light-picks 1, 4, 16) against every light on the bench scenes with 64 "
                   "added point lights: GPU ms, MSE against the converged frame, MSE at equal time", _lights),
    "peers": Area("frames/s against pyrender", _peers),
    "tradeoff": Area("every knob's GPU ms vs error against the reference", _tradeoff, FLIP, workers="one"),
    "budget": Area("effects per material chosen under --budget-ms", _budget, FLIP, workers="one"),
    "motion": Area("the trade along head trajectories (slow looks, fast turns, walks, glances at 90 and 120 Hz): "
                   "per-frame FLIP against each frame's reference, flicker, GPU ms", _motion, FLIP),
    "crosscheck": Area("the reference vs Mitsuba 3 on the Cornell boxes", _crosscheck, ("mitsuba",) + FLIP),
    "workers": Area("frames/s of a capture path in one process and on --workers N,M Ray workers", _workers,
                    workers="list"),
    "vr": Area("the headset's frame on --poses N seeded head poses (--pose-seed; half gaze at the scene's content, "
               "half random): camera model (--cameras) x "
               "MSAA (--counts) x materials config (--configs shadows,room,budget): GPU ms per pass and frame, "
               "median / worst / best over the poses", _vr),
}


def areas_help() -> str:
    return "; ".join(f"{name}: {area.help}" for name, area in AREAS.items())


def run_area(args, out, camera_from_args) -> None:
    """Run bench `args.area` into the folder `out` (checked already): its optional extras and Ray
    first (one error before any work), then the area's own run."""
    from ..util.extras import require

    area = AREAS.get(args.area)
    if area is None:
        raise ValueError(f"unknown benchmark area {args.area!r}; choose from {', '.join(AREAS)}")
    for module in area.needs:
        require(module, f"bench {args.area}")
    if args.workers or area.workers == "list":
        from ..app.cluster import require_ray

        require_ray()  # the optional extra, before any work
        if not area.workers:
            spread = " and ".join(n for n, a in AREAS.items() if a.workers == "one")
            raise ValueError(f"--workers spreads the {spread} sweeps; bench {args.area} runs in one process")
        args.workers_list = [int(x) for x in args.workers.split(",")] if args.workers else None
        if area.workers == "one":
            if len(args.workers_list) != 1:
                raise ValueError(f"bench {args.area} --workers takes one count, got {args.workers!r}")
            args.workers = args.workers_list[0]
    area.run(args, out, camera_from_args)
