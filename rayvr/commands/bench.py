"""`rayvr bench AREA`: the GPU benchmarks (their table: rayvr/bench/__init__.py AREAS)."""
from __future__ import annotations

import argparse

import numpy as np

from .. import settings as settings_mod
from ..accel.bvh import BUILDS
from ..gl.gpu_layout import BVH_LAYOUTS
from .args import FOV, FRAMES, add_camera_model_arguments, add_connect_timeout_argument, camera_from_args
from .args import add_device_argument, count as _count, size as _size

COMMAND = "bench"
REPEAT = _count(1, 100_000)  # bench --repeat: timed frames per measurement
MAX_POSES = 10_000  # bench vr --poses
MAX_SEED = 2**63 - 1  # bench vr --pose-seed: numpy's generators take any non-negative integer
# Where results go unless --out says: a working folder, never the repository's committed results.
DEFAULT_OUT = "bench-out"


def _worker_counts(text: str) -> str:
    """argparse type: comma-separated worker counts, each from 1 to 1024 (kept as text)."""
    try:
        counts = [int(x) for x in text.split(",")]
    except ValueError:
        counts = []
    if not counts or not all(1 <= c <= 1024 for c in counts):
        raise argparse.ArgumentTypeError(f"expected worker counts from 1 to 1024, comma-separated, got {text[:40]!r}")
    return text


def _split(text: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip())


def _among(text: str, what: str, allowed, unique: bool = False) -> tuple[str, ...]:
    """Comma-separated names, each in `allowed` (`unique`: repeats dropped)."""
    names = tuple(dict.fromkeys(_split(text))) if unique else _split(text)
    if not names or any(x not in allowed for x in names):
        raise argparse.ArgumentTypeError(f"{what} must be among {', '.join(allowed)}, got {text!r}")
    return names


def _knob_names(text: str) -> tuple[str, ...]:
    """bench tradeoff --knobs: comma-separated knob names (checked against a scene's knobs when it runs)."""
    names = tuple(dict.fromkeys(_split(text)))
    if not names:
        raise argparse.ArgumentTypeError(f"expected knob names, comma-separated, got {text!r}")
    return names


def _view_names(text: str) -> tuple[str, ...]:
    """bench tradeoff/budget --only-views: "fixed" and head pose numbers -> ("fixed", "pose 3", ...)."""
    out = []
    for x in dict.fromkeys(_split(text)):
        if x == "fixed":
            out.append(x)
        elif x.isdigit() and int(x) < MAX_POSES:
            out.append(f"pose {int(x)}")
        else:
            raise argparse.ArgumentTypeError(f"views are 'fixed' and head pose numbers 0 to {MAX_POSES - 1}, "
                                             f"comma-separated; got {x!r} in {text!r}")
    if not out:
        raise argparse.ArgumentTypeError(f"expected views (fixed, 0, 1, ...), got {text!r}")
    return tuple(out)


def _builds(text: str) -> tuple[str, ...]:
    return _among(text, "BVH builds", BUILDS, unique=True)


def _layouts(text: str) -> tuple[str, ...]:
    return _among(text, "BVH layouts", BVH_LAYOUTS)


def _variants(text: str) -> dict:
    """bench vr --variants "NAME:option=value,option=value;NAME2:..." -> {name: {field: value}}, each
    value parsed and checked by its render option (an empty list of options: the settings as given)."""
    known, out = settings_mod.all_options(), {}
    for part in filter(None, (p.strip() for p in text.split(";"))):
        name, sep, fields = part.partition(":")
        name = name.strip()
        if not sep or not name or name in out:
            raise argparse.ArgumentTypeError(f"--variants: each variant is NAME:option=value,... with its own "
                                             f"name, got {part!r}")
        out[name] = {}
        for item in filter(None, (f.strip() for f in fields.split(","))):
            key, eq, value = item.partition("=")
            option = known.get(key.strip().replace("-", "_"))
            if not eq or option is None:
                raise argparse.ArgumentTypeError(f"--variants {name}: {item!r} is not option=value with a render "
                                                 f"option (rayvr options lists them)")
            try:
                out[name][option.name] = option.from_text(value.strip())
            except ValueError as exc:
                raise argparse.ArgumentTypeError(f"--variants {name}: {exc}") from None
    if not out:
        raise argparse.ArgumentTypeError("--variants names at least one variant")
    return out


def _ray_orders(text: str) -> tuple[str, ...]:
    from ..render_options.ray_order import RAY_ORDERS
    return _among(text, "ray orders", RAY_ORDERS, unique=True)


def _persistent_modes(text: str) -> tuple[str, ...]:
    from ..render_options.persistent_threads import PERSISTENT_MODES
    return _among(text, "persistent modes", PERSISTENT_MODES, unique=True)


def _names(text: str) -> tuple[str, ...]:
    names = _split(text)
    if not names:
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return names


def _sample_counts(text: str) -> tuple[int, ...]:
    from ..frame.cameras.sampling import SAMPLE_COUNTS

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
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not values or not all(np.isfinite(values)) or min(values) <= 0:
        raise argparse.ArgumentTypeError(f"budgets must be positive numbers, got {text!r}")
    return values


def add_parser(sub) -> None:
    from ..bench import AREAS, areas_help
    from ..bench.head_poses import POSE_SEED

    b = sub.add_parser("bench", help="GPU benchmarks (run on a real GPU)")
    b.add_argument("area", choices=tuple(AREAS), help=areas_help())
    budget = b.add_mutually_exclusive_group()
    budget.add_argument("--budget-ms", type=_budgets,
                        help="budget: the frame budgets, comma-separated (default: 90 and 120 Hz, 11.1 and 8.33 ms); "
                             "vr: the one budget of its budget config (default 11.1)")
    budget.add_argument("--budget-hz", type=_budgets, metavar="HZ",
                        help="the budgets as display rates, comma-separated (90 is 11.1 ms, 120 is 8.33 ms)")
    b.add_argument("--frame-knobs", metavar="GRID",
                   help="budget: the frame-wide knobs the pick chooses too, every combination of the values given, "
                        "e.g. \"stereo=dual,reuse;spp=1,4;denoise=off,on;msaa=1,4;scale=0.75,1\"; also "
                        "temporal=off,on, camera=pinhole,foveated and iterations=1..6 (the denoiser's; default: none; "
                        "docs/budget.md)")
    b.add_argument("--rung-params", metavar="SETTINGS",
                   help="budget: per-material settings a material may take beside each effect's own, e.g. "
                        "\"glossy.samples=1,4;path.samples=1,4\" (each a rung: one more render per point of the "
                        "grid; default: none; docs/budget.md)")
    b.add_argument("--knobs", type=_knob_names, metavar="NAMES",
                   help="tradeoff: sweep only these knobs, comma-separated: a knob (path.samples, stereo) or its "
                        "family (path, path_everywhere); the folder's earlier rows of the other knobs stay "
                        "(default: every knob)")
    b.add_argument("--out", default=DEFAULT_OUT, help=f"folder for JSON/markdown results (default ./{DEFAULT_OUT}: "
                   "the repository's committed bench/results/ is only written when named)")
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
    b.add_argument("--ray-order", dest="ray_orders", type=_ray_orders, metavar="ORDERS",
                   help="rays, vr, gi: the wavefront ray orders to time, comma-separated among none,morton (a grid "
                        "axis; default none; rays: given, also the glossy and path frames; gi: the path and photon "
                        "frames)")
    b.add_argument("--persistent", dest="persistent_modes", type=_persistent_modes, metavar="MODES",
                   help="rays, vr, gi: the wavefront trace kernels' modes to time, comma-separated among off,on (a "
                        "grid axis; default off; rays: given, also the glossy and path frames; gi: the path and "
                        "photon frames)")
    b.add_argument("--no-tiles", action="store_true", help="rays, primary: leave out the tile frustum culling variant")
    b.add_argument("--variants", type=_variants, metavar="SPEC",
                   help='vr: named render-option variants, a grid axis: "NAME:option=value,...;NAME2:...", e.g. '
                        '"entries:;lists:tile_lists=256;blocks:block_culling=on,tile_lists=256" (each on top of '
                        'the render flags given)')
    b.add_argument("--workers", type=_worker_counts, help="tradeoff/budget: spread the variants over N Ray workers; "
                   "workers: the worker counts to time (default 1,2); needs pip install 'rayvr[cluster]'")
    b.add_argument("--address", help="with --workers: an existing Ray cluster, 'auto' or HOST:PORT")
    add_connect_timeout_argument(b)
    b.add_argument("--frames", type=FRAMES, default=64, help="workers: frames of the capture path (default 64)")
    b.add_argument("--backend", choices=("egl", "osmesa"))
    add_device_argument(b)
    b.add_argument("--fov", type=FOV, help="primary: vertical field of view of the --camera-model row")
    b.add_argument("--configs", type=_names,
                   help="primary: the bench views' rows to measure, comma-separated, alone (default: the paper's "
                        "Table 5 rows at 2160x1200, then raster_gbuffer, pinhole at --size; among raster_gbuffer, "
                        "pinhole, distorted, distorted_chromatic, foveated, wide_210x130, dof_0.5m, dof_0.25m, "
                        "dof_0.1m); gi: the parts to measure (default all: photon, reuse, path); vr: the materials "
                        "configs (default shadows,room,budget; also ssr: the hybrid frame's mirrors on ssr); rays: the ray kinds (default all: primary, shadow, "
                        "reflect, glossy_0.1, glossy_0.3, glossy_0.6, diffuse, area_shadow)")
    b.add_argument("--reference-spp", type=_count(16, 1 << 16),
                   help="gi: samples per pixel of the path reference (default 1024; --quick 64); tradeoff, budget: "
                        "of the reference every variant is judged against, in two halves with their own seeds whose "
                        "FLIP is the noise floor, rounded to whole frames of 64 samples a half (default 2048; --quick 128)")
    b.add_argument("--reference-photons", type=_count(256, 1 << 22),
                   help="gi: photon paths of the photon tables' reference (default 4194304; --quick 32768)")
    b.add_argument("--counts", type=_sample_counts,
                   help="primary: sub-rays per sample of the bench views' rows, comma-separated (default 1,4,16); "
                        "vr: the MSAA counts (default 1,4,16,32)")
    b.add_argument("--cameras", type=_names,
                   help="vr: the camera models, comma-separated among primary's --configs names (default "
                        "raster_gbuffer,pinhole,distorted_chromatic,foveated,wide_210x130,dof_0.5m)")
    b.add_argument("--poses", type=_count(0, MAX_POSES),
                   help="vr: head poses per scene, the even-numbered gazing at a point of the scene's content, the "
                        "odd-numbered random (default 8; --quick 2); lights, tradeoff, budget: the head poses measured "
                        "beside the fixed view (default 8; --quick: lights and budget 1, tradeoff 0; 0: the fixed "
                        "view only)")
    b.add_argument("--only-views", type=_view_names, metavar="VIEWS",
                   help="tradeoff, budget: only these views, comma-separated: fixed and head pose numbers, e.g. "
                        "fixed,0 or 1,2 (instead of --poses; the folder's report keeps the views a run leaves out, "
                        "so runs of some views add up)")
    b.add_argument("--pose-seed", type=_count(0, MAX_SEED), default=POSE_SEED,
                   help=f"vr, tradeoff, budget, lights: the seed the head poses are drawn from (default {POSE_SEED})")
    add_camera_model_arguments(b)
    settings_mod.add_arguments(b, COMMAND)
    b.set_defaults(func=cmd_bench)


def cmd_bench(args) -> int:
    from ..bench import run_area
    from ..util.output import check_output_dir

    out = check_output_dir(args.out)  # before any measuring: results are written after it
    run_area(args, out, camera_from_args)
    print(f"results in {out}/{args.area}.json and {args.area}.md")
    return 0
