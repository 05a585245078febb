"""`rayvr bench vr`: the frame a headset asks for, timed on seeded head poses.

Per scene (the built-in room `default`, and Sponza from the shared scenes when present), `poses`
head poses are drawn inside the room or Sponza's nave (rayvr/bench/head_poses.py: the even-numbered
gaze at a visible point of the scene's content, furniture, mirrors, pillars, arches, not its walls,
floors and ceilings; the odd-numbered look about at random, yaw drawn over the whole turn, pitch
within +-20 degrees; the bench rig's IPD, fov and near plane), and every cell of a grid is timed on
each of them:

  materials config x variant x camera model x MSAA count

- materials configs (MATERIAL_CONFIGS): `shadows`, shadows on every material plus the scene's mirrors
  on one-bounce BVH reflections (bench/rays.py MIRRORS: what `bench rays` and `bench stereo` call the
  hybrid frame); `ssr`, the same with the mirrors on `ssr` (the depth quadtree first: does the
  cheaper rung cost less on the same views?); `room`, rayvr/assets/default_room.toml (the room only); `budget`, the effects
  capture's `--budget-ms` picks for `budget_ms` (default 11.1 ms, a 90 Hz frame), chosen once per
  scene on its bench view at the bench's size, starting from the scene's shipped config;
- variants: extra RenderSettings fields per row ({name: {field: value}}, default one variant
  `default` without any), so rows such as a renderer switch on and off need no new bench;
- camera models: bench/primary.py CONFIGS, ray-cast primary visibility (the pinhole's `pinhole`
  row too), with the raster G-buffer pinhole row `raster_gbuffer` (1x only) for reference;
- MSAA: sub-rays per sample (RenderSettings.msaa).

Each (cell, pose) is one row of vr.json: the median GPU ms of the frame and of every pass over
`repeat` frames after a warm-up that lasts until frame times settle (bench/rays.py time_frame; GL
timer queries), `visibility_ms`, what makes the G-buffer (bench/primary.py's definition), and
what a render loop meets (bench/rays.py time_pipelined): `record_ms`, the CPU's recording of a
frame, and `pipelined_ms`, the wall time a frame of frames recorded back to back (where the CPU is
the slower, the GPU's idle time falls inside the passes' timer windows and `frame_ms` overstates
the GPU's work), and `rays`: each traced effect's closest-hit and shadow rays of one more frame,
counted on the GPU (frame/passes/trace_effect.py count_rays), per pixel and per second of its pass
(vr.md: per pixel of the effect, for the worst pose). Each row also records `effect_share`, what the frame shows: the share of its pixels
(both eyes) whose material the config gives each effect, and "background" for the pixels that hit
nothing, from the G-buffer's material ids of one more frame read back after the timed ones, once per
(pose, config, camera: a camera model's fov and lens change the view). vr.md has a table per scene:
each cell's median, worst and best frame over the poses, the pose that was worst (with its kind),
what the frame shows (median over the poses, and on the worst pose) and its most expensive passes;
the targets are judged on the worst pose. The report is rewritten after every cell (a run cut short keeps
what it measured); rows of the scenes and configs a run does not measure stay from the folder's
earlier vr.json when it was taken on the same device with the same size, poses and seed, so the
scenes and configs can run as separate commands.
"""
from __future__ import annotations

import itertools
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..frame.cameras.rig import StereoRig
from ..gl.context import create_context
from ..renderer import Renderer, RenderSettings
from ..scene.materials import load_config
from ..frame.passes.primary_rays import KNOB_DEFAULTS, MEASURED_CHOICES, PRIMARY_KNOBS
from ..frame.passes.trace_effect import count_rays
from ..util.output import atomic_write_bytes
from .head_poses import (EYE_HEIGHT_M, MAX_GAZE_PITCH_DEG, MAX_PITCH_DEG, MIN_TARGET_M, POSE_SCHEME, POSE_SEED,
                         draw_poses, pose_bounds, pose_label, region)
from .primary import CONFIGS as CAMERA_CONFIGS
from .rays import MIRRORS, hybrid_config, time_frame, time_pipelined, time_stages
from .report import device_meta, earlier_rows, effect_share, share_text, write_report
from .scenes import bench_scenes, shipped_config

MATERIAL_CONFIGS = ("shadows", "ssr", "room", "budget")
# the hybrid configs: shadows everywhere, the mirrors on BVH reflections or on screen-space ones
HYBRID_MIRRORS = {"shadows": "reflections", "ssr": "ssr"}
DEFAULT_CONFIGS = ("shadows", "room", "budget")  # what bench vr measures unless --configs names others
CAMERAS = ("raster_gbuffer", "pinhole", "distorted_chromatic", "foveated", "wide_210x130", "dof_0.5m")
COUNTS = (1, 4, 16, 32)
POSES = 8
BUDGET_MS = 11.1  # a 90 Hz headset's frame
VARIANTS = {"default": {}}
GRID_FIELDS = ("primary", "msaa")  # the grid sets these per row; a variant may not
# The first pose of a cell warms the clocks that long at least (0.3 s left first poses up to 3x
# slow on the H200); the next ones settle only.
WARMUP_S = 1.0
# A scene's first cell warms this long at least: after the scene's build its frames settled at the
# idle clock (the room's first 1x pose measured 3x slow on the H200, 2026-12-03 late/vr_variants_room).
SCENE_WARMUP_S = 2.0
TOP_PASSES = 3  # passes vr.md names per cell
# what --quick measures (CI, llvmpipe): the room, tiny, two poses, a few cells
QUICK = {"size": (32, 24), "poses": 2, "cameras": ("raster_gbuffer", "pinhole", "distorted_chromatic"),
         "counts": (1, 4), "configs": ("shadows", "room")}
# earlier rows are kept only when these meta entries match
SAME_RUN = ("gl_renderer", "gl_version", "per_eye_size", "quick", "poses", "pose_seed", "pose_scheme")
CHOICES_FILE = "primary_visibility.json"  # with several variants: the renderer's measured choices, renewed
CHOICE_MARGIN = 0.03  # a worst time within 3 % of the least is a tie (single frames vary about that much)


def checked_variants(variants) -> dict:
    """{name: RenderSettings fields}, each refused in one line before any work when RenderSettings
    does not take it or it sets a field the grid sets."""
    variants = dict(VARIANTS if variants is None else variants)
    if not variants:
        raise ValueError("bench vr needs at least one variant")
    for name, fields in variants.items():
        clash = [f for f in fields if f in GRID_FIELDS]
        if clash:
            raise ValueError(f"bench vr variant {name!r} sets {', '.join(clash)}, which the grid sets per row")
        try:
            RenderSettings.from_dict(fields)
        except ValueError as exc:  # an unknown option or a bad value
            raise ValueError(f"bench vr variant {name!r}: {exc}") from None
    return variants


def checked_grid(cameras, counts, configs) -> None:
    from ..frame.cameras.sampling import SAMPLE_COUNTS

    for what, names, allowed in (("--cameras", cameras, CAMERA_CONFIGS), ("--configs", configs, MATERIAL_CONFIGS),
                                 ("--counts", counts, SAMPLE_COUNTS)):
        if not names or any(x not in allowed for x in names):
            raise ValueError(f"bench vr {what} must be among {', '.join(map(str, allowed))}, "
                             f"got {','.join(map(str, names)) or 'none'}")


def cells(cameras, counts, configs, variants) -> list[tuple]:
    """(config, variant, camera, msaa) in the order they are timed: the raster reference at 1x only."""
    return [(c, v, cam, n) for c in configs for v in variants for cam in cameras for n in counts
            if CAMERA_CONFIGS[cam][2] == "rays" or n == 1]


def materials_config(gl, config: str, name: str, scene, rig, budget_ms: float, progress: bool):
    """The MaterialConfig of `config` for scene `name` and what to record about it, or (None, why)
    where it does not apply. `budget` renders its pick on `gl` through `rig` (capture's --budget-ms)."""
    if config in HYBRID_MIRRORS:
        mirrors = HYBRID_MIRRORS[config]
        return hybrid_config(name, mirrors), {"default": "shadows", mirrors: list(MIRRORS.get(name, ())), "bounces": 1}
    if config == "room":
        if name != "default":
            return None, "the room's config (default_room.toml) is the room's only"
        return load_config(shipped_config(name)), {"file": "rayvr/assets/default_room.toml"}
    from ..quality.budget import describe_pick
    from ..quality.frame_budget import auto_config

    base = shipped_config(name)
    with Renderer(scene, load_config(base), gl=gl) as r:
        picked, pick = auto_config(r, rig, budget_ms, progress=progress)
    if progress:
        print(describe_pick(pick), flush=True)
    return picked, {"budget_ms": budget_ms, "base": base.name if base else "all raster",
                    "picked_on": "the bench view (pinhole, default render settings)", **pick}


STAGE_FRAMES = 3  # frames timed kernel by kernel for the primary visibility's stages


def primary_stages(r: Renderer, rig: StereoRig) -> dict:
    """Median GPU ms of each kernel of the primary_rays pass ("cull", "lists", "trace", ...), summed
    over a frame's rounds, over STAGE_FRAMES frames timed kernel by kernel (rays.time_stages)."""
    return {k.split(".", 1)[1]: v for k, v in time_stages(r, rig, "primary_rays.", STAGE_FRAMES).items()}


def round_passes(r: Renderer, rig: StereoRig) -> dict:
    """GPU ms of each pass that runs once per round (MSAA, shared channel shading), round by round,
    from one more frame: a round that shades few pixels shows what it costs regardless of them.
    A frame without rounds (not sampled) has none: no frame is recorded for it."""
    if not r.plan(camera=rig.camera).sampled:
        return {}
    fc = r.record(rig, "both", "color")
    return {k: [round(v, 4) for v in ms] for k, ms in r.read_round_ms(fc).items() if len(ms) > 1}


def worst_row(rows, cell: dict) -> dict:
    """The row of a spread() cell's worst pose."""
    return next(r for r in rows if r["scene"] == cell["scene"] and r["pose"]["index"] == cell["worst_pose"]
                and all(r[k] == cell[k] for k in ("config", "variant", "camera", "msaa")))


def round_totals(row: dict) -> list[float]:
    """A row's ms of each round in the order run (its round_passes summed over the passes)."""
    per_pass = list(row.get("round_passes", {}).values())
    return [float(sum(ms)) for ms in itertools.zip_longest(*per_pass, fillvalue=0.0)]


def frame_row(r: Renderer, rig: StereoRig, repeat: int, warmup: int, warmup_s: float) -> dict:
    names, med, total = time_frame(r, rig, repeat, warmup, warmup_s)
    loop = time_pipelined(r, rig)
    passes = {k: med[k] for k in names if k in med}
    visibility = passes.get("visibility", 0.0) + passes.get("primary_rays", 0.0) + passes.get("gbuffer", 0.0)
    stages = primary_stages(r, rig) if "primary_rays" in passes else {}
    return {"frame_ms": total, "visibility_ms": visibility, "passes": passes, "primary_stages": stages,
            "round_passes": round_passes(r, rig), "rays": effect_rays(r, rig, passes), **loop}


def effect_rays(r: Renderer, rig: StereoRig, passes: dict) -> dict:
    """The rays each traced effect's pass traced in one more frame, counted on the GPU
    (trace_effect.count_rays: closest hits and shadow rays, every round), per pixel of the frame
    (both eyes), and the pass's rays per second at its median ms in the timed frames."""
    pixels = 2 * rig.size[0] * rig.size[1]
    out = {}
    for effect, n in count_rays(r, rig).items():
        ms = passes.get(f"rt_{effect}", 0.0)
        total = n["closest"] + n["shadow"]
        out[effect] = {"closest": n["closest"], "shadow": n["shadow"],
                       "closest_per_pixel": n["closest"] / pixels, "shadow_per_pixel": n["shadow"] / pixels,
                       "grays_per_s": total / ms / 1e6 if ms > 0 else None}
    return out


def rays_text(rays: dict, share: dict | None) -> str:
    """vr.md's words for a row's `rays`: per effect in view, the rays a pixel of that effect traces
    (closest + shadow; its share of the frame from `share`) and the pass's GRays/s."""
    parts = []
    for effect, n in rays.items():
        own = (share or {}).get(effect, 0.0)
        if own <= 0:
            continue
        closest, shadow = n["closest_per_pixel"] / own, n["shadow_per_pixel"] / own
        speed = f", {n['grays_per_s']:.1f} GRays/s" if n.get("grays_per_s") else ""
        parts.append(f"rt_{effect} {closest + shadow:.1f} rays a pixel of it ({closest:.1f} closest + "
                     f"{shadow:.1f} shadow){speed}")
    return "; ".join(parts) or "no traced effect in view"


def frame_share(r: Renderer, rig: StereoRig, config) -> dict:
    """report.effect_share of one frame of `r` through `rig` under its settings (stereo `warp`
    read as `dual`: warp has no per-eye G-buffer): a frame rendered and read back apart from the
    timed ones."""
    settings = r.settings
    if settings.stereo == "warp":
        r.settings = replace(settings, stereo="dual")
    try:
        f = r.render(rig, aux=("material",))
    finally:
        r.settings = settings
    return effect_share([f.left.aux["material"], f.right.aux["material"]], r.scene.material_names(), config)


def kept_rows(path: Path, meta: dict, measured: set) -> tuple[list, dict]:
    """Rows of an earlier vr.json at `path` whose (scene, config) this run does not measure, and
    that run's per-scene meta, if it matches this run (SAME_RUN); else nothing."""
    rows, om = earlier_rows(path, meta, SAME_RUN, lambda r: (r["scene"], r["config"]) not in measured)
    try:
        return rows, {s: m for s, m in om["scenes"].items() if any(r["scene"] == s for r in rows)}
    except (KeyError, TypeError, AttributeError):
        return [], {}


def loop_cell(s: dict) -> str:
    """vr.md's "CPU record / pipelined frame" cell of a spread() entry."""
    if s.get("record_ms") is None:
        return "-"
    return f"{s['record_ms']:.3f} / {s['pipelined_ms']:.3f}"


def spread(rows) -> list[dict]:
    """Per scene and cell (config, variant, camera, msaa): frame ms median / worst / best over the
    poses, the worst pose (its label names its kind), the median visibility ms and the median of each
    pass, most expensive first, and what the frame shows: each effect's median share over the poses
    (the medians need not add up to 1) and the worst pose's shares."""
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["scene"], r["config"], r["variant"], r["camera"], r["msaa"]), []).append(r)
    out = []
    for (scene, config, variant, camera, msaa), group in groups.items():
        frame = [g["frame_ms"] for g in group]
        worst = group[int(np.argmax(frame))]
        passes = {k: float(np.median([g["passes"].get(k, 0.0) for g in group])) for k in group[0]["passes"]}
        stages = {k: float(np.median([g.get("primary_stages", {}).get(k, 0.0) for g in group]))
                  for k in group[0].get("primary_stages", {})}
        shares = [g.get("effect_share") for g in group]
        effects = list(dict.fromkeys(k for sh in shares if sh for k in sh))
        share = ({k: float(np.median([sh.get(k, 0.0) for sh in shares])) for k in effects}
                 if all(shares) else None)  # rows from before shares were recorded: none
        out.append({"scene": scene, "config": config, "variant": variant, "camera": camera, "msaa": msaa,
                    "primary": group[0]["primary"], "poses": len(group), "median_ms": float(np.median(frame)),
                    "worst_ms": max(frame), "best_ms": min(frame), "worst_pose": worst["pose"]["index"],
                    "worst_pose_label": pose_label(worst["pose"]),
                    "worst_pose_kind": worst["pose"].get("kind", "random"),  # rows from before kinds: random
                    "effect_share": share,
                    "worst_effect_share": worst.get("effect_share"),
                    "visibility_median_ms": float(np.median([g["visibility_ms"] for g in group])),
                    "visibility_worst_ms": max(g["visibility_ms"] for g in group),
                    # the CPU's recording and the render loop's frame (rows from before they were timed: None)
                    **{k: (float(np.median([g[k] for g in group])) if all(k in g for g in group) else None)
                       for k in ("record_ms", "pipelined_ms")},
                    "passes": dict(sorted(passes.items(), key=lambda kv: -kv[1])), "primary_stages": stages})
    return out


def judged_ms(row: dict) -> float:
    """What a primary-visibility choice is judged by: the row's `primary_rays` pass, the only pass
    its knobs change (the frame's other passes add their own noise: on Sponza's worst poses they
    picked shapes whose primary pass was 4-7 % slower, bench/results/h200/2026-12-03/shapes); the
    frame where a row has no passes."""
    return row.get("passes", {}).get("primary_rays", row["frame_ms"])


def primary_choices(rows) -> dict:
    """Per camera model and MSAA count, which variant casts primary rays fastest: among the ray-cast
    rows of the variants that set only primary-visibility knobs (primary_rays.PRIMARY_KNOBS), measured
    on the same (scene, config, pose, camera) cells, the one whose worst `primary_rays` pass over them
    is least (`judged_ms`), or the first variant of the run within CHOICE_MARGIN of it (list the
    simpler variants first: a win inside the timings' noise is no reason for more machinery).
    {model: {msaa: {"variant", "knobs" (the plan's), "worst_ms" {variant: ms}}}}."""
    order = list(dict.fromkeys(r["variant"] for r in rows))
    cells: dict = {}
    for r in rows:
        if r["primary"] != "rays" or any(k not in PRIMARY_KNOBS for k in r.get("variant_fields", {})):
            continue
        key = (r["camera_model"], r["msaa"])
        cell = (r["scene"], r["config"], r["pose"]["index"], r["camera"])
        cells.setdefault(key, {}).setdefault(r["variant"], {})[cell] = r
    out: dict = {}
    for (model, msaa), by_variant in sorted(cells.items()):
        common = set.intersection(*(set(v) for v in by_variant.values()))
        if not common:
            continue
        worst = {name: max(judged_ms(v[c]) for c in common) for name, v in by_variant.items()}
        least = min(worst.values())
        best = next(name for name in order if name in worst and worst[name] <= least * (1.0 + CHOICE_MARGIN))
        plan = by_variant[best][next(iter(common))]
        out.setdefault(model, {})[msaa] = {"variant": best, "worst_ms": worst,
                                           "knobs": {k: plan.get(k, KNOB_DEFAULTS.get(k)) for k in PRIMARY_KNOBS}}
    return out


def choices_file(chosen: dict, meta: dict, out: Path) -> dict:
    """The successor of the renderer's measured choices file (primary_rays.MEASURED_CHOICES): the
    models and counts this run measured replaced by its choices, the rest kept."""
    shipped = json.loads(MEASURED_CHOICES.read_text())
    merged = {m: dict(counts) for m, counts in shipped["choices"].items()}
    for model, counts in chosen.items():
        for msaa, c in counts.items():
            merged.setdefault(model, {})[str(msaa)] = c["knobs"]
    run = (f"{out} ({meta.get('date')}, {meta['poses']} poses a scene, seed {meta['pose_seed']}, "
           f"{'x'.join(map(str, meta['per_eye_size']))} an eye): " +
           ", ".join(f"{m} {','.join(str(n) for n in counts)}x" for m, counts in chosen.items()))
    return {**shipped, "measured": [run] + [m for m in shipped.get("measured", []) if m != run],
            "device": f"{meta.get('gl_renderer')}, {meta.get('gl_version')}", "choices": merged}


# Targets for the headset's frame, judged on the worst pose: (name, what, camera, msaa,
# kind, bound) where kind "ms" bounds the primary_rays pass, "grays" is a least rate of its 1x rays
# (GRays/s), and "ratio:<camera>:<msaa>" bounds the frame against that cell's frame on the same pose
# and config.
TARGETS = (
    ("msaa16_primary", "16x MSAA primary visibility <= 3.0 ms", "pinhole", 16, "ms", 3.0),
    ("msaa32_primary", "32x MSAA primary visibility <= 5.0 ms", "pinhole", 32, "ms", 5.0),
    ("chromatic_frame", "distorted chromatic frame <= 1.25x the pinhole ray-cast frame", "distorted_chromatic", 1,
     "ratio:pinhole:1", 1.25),
    ("msaa4_frame", "4x MSAA frame <= 1.3x the 1x ray-cast frame", "pinhole", 4, "ratio:pinhole:1", 1.3),
    ("primary_rate", "1x ray-cast primary visibility >= 6 GRays/s", "pinhole", 1, "grays", 6.0),
)


def targets(rows, per_eye_size) -> list[dict]:
    """Each target of TARGETS per scene and variant whose cells were measured: the worst pose's
    figure (over the poses and configs), that pose (its label names its kind) and whether it meets
    the bound."""
    w, h = per_eye_size
    cell = {(r["scene"], r["config"], r["variant"], r["camera"], r["msaa"], r["pose"]["index"]): r for r in rows}
    labels = {(r["scene"], r["pose"]["index"]): pose_label(r["pose"]) for r in rows}
    out = []
    for scene, variant in dict.fromkeys((r["scene"], r["variant"]) for r in rows):
        for name, what, camera, msaa, kind, bound in TARGETS:
            figures = []  # (figure, pose, config)
            for (sc, config, var, cam, n, pose), r in cell.items():
                if (sc, var, cam, n) != (scene, variant, camera, msaa):
                    continue
                primary_ms = r["passes"].get("primary_rays", 0.0)
                if kind == "ms":
                    figures.append((primary_ms, pose, config))
                elif kind == "grays" and primary_ms > 0:
                    figures.append((2 * w * h / primary_ms / 1e6, pose, config))
                elif kind.startswith("ratio:"):
                    _, base_camera, base_msaa = kind.split(":")
                    base = cell.get((sc, config, var, base_camera, int(base_msaa), pose))
                    if base is not None:
                        figures.append((r["frame_ms"] / base["frame_ms"], pose, config))
            if not figures:
                continue
            lowest_is_worst = kind == "grays"
            figure, pose, config = min(figures) if lowest_is_worst else max(figures)
            out.append({"scene": scene, "variant": variant, "target": name, "what": what, "bound": bound,
                        "worst": figure, "worst_pose": pose, "worst_pose_label": labels[(scene, pose)],
                        "worst_config": config,
                        "met": figure >= bound if lowest_is_worst else figure <= bound})
    return out


def markdown(result: dict) -> str:
    meta, rows = result["meta"], result["rows"]
    w, h = meta["per_eye_size"]
    lines = ["# rayvr bench vr: the headset's frame on seeded head poses", "",
             f"- **device**: {meta.get('gl_renderer')} ({meta.get('gl_vendor')}), driver {meta.get('gl_version')}",
             f"- **resolution**: 2x{w}x{h} (both eyes, {w}x{h} each)",
             f"- **poses**: {meta['poses']} per scene, seed {meta['pose_seed']} (--pose-seed); eye height "
             f"{EYE_HEIGHT_M[0]}-{EYE_HEIGHT_M[1]} m above the floor, no roll; even-numbered poses (content) gaze "
             f"at a visible point of the scene's content (not its walls, floors, ceilings or lights) at least "
             f"{MIN_TARGET_M:g} m away, pitch within +-{MAX_GAZE_PITCH_DEG:g} deg; odd-numbered (random) yaw "
             f"0-360 deg, pitch within +-{MAX_PITCH_DEG:g} deg; the bench rig's IPD, fov and near plane"
             + ("" if meta.get("pose_scheme") else " (rows from before content poses: every pose random)"),
             "- **frame shows**: the share of the frame's pixels (both eyes) whose material the config gives each "
             "effect, background: pixels that hit nothing; from the material ids of one frame read back after the "
             "timed ones (per pose, config and camera)",
             f"- **timing**: {meta['what_times_include']}",
             f"- **grid**: configs {', '.join(meta['configs'])}; variants "
             + ", ".join(f"{k} {json.dumps(v)}" for k, v in meta["variants"].items())
             + f"; cameras {', '.join(meta['cameras'])}; MSAA {', '.join(map(str, meta['counts']))}",
             f"- **date**: {meta.get('date')}, rayvr {meta.get('rayvr')}, {meta['seconds']:.0f} s"]
    if not meta.get("timings_meaningful", True):
        lines.append("- **A software rasterizer: its GL timer queries do not measure GPU work; the ms are for "
                     "correctness only.**")
    if meta.get("kept_rows"):
        lines.append(f"- **kept**: {meta['kept_rows']}")
    for name, why in meta.get("skipped", {}).items():
        lines.append(f"- **skipped** {name}: {why}")
    lines.append("")
    summary = spread(rows)
    for scene in dict.fromkeys(r["scene"] for r in rows):
        sm = meta["scenes"].get(scene, {})
        b = sm.get("pose_bounds", {})
        lines += [f"## {scene}", "", f"Heads inside {sm.get('region', '')}: "
                  + ", ".join(f"{a} {lo:.2f} to {hi:.2f} m" for a, (lo, hi) in b.items())
                  + f"; IPD {sm.get('ipd')} m, fov {sm.get('fov_y')} deg, near {sm.get('near')} m.", ""]
        for config, why in sm.get("configs_skipped", {}).items():
            lines += [f"Config {config} not measured: {why}.", ""]
        for cell, why in sm.get("cells_skipped", {}).items():
            lines += [f"Cell {cell} not measured: {why}.", ""]
        if "budget" in sm.get("configs", {}):
            pick = sm["configs"]["budget"]
            by_effect: dict = {}
            for material, effect in pick["assignment"].items():
                by_effect.setdefault(effect, []).append(material)
            fit = ("within it" if pick["within_budget"] else "OVER it") + ("" if pick["feasible"] else
                                                                            ", the cheapest assignment")
            lines += [f"Config budget: `--budget-ms {pick['budget_ms']:g}` picked on {pick['picked_on']} from "
                      f"{pick['base']}: measured {pick['measured_ms']:.2f} ms there ({fit}); "
                      + "; ".join(f"{e}: {', '.join(sorted(m))}" for e, m in sorted(by_effect.items())) + ".", ""]
        lines += ["| config | variant | camera | primary | MSAA | poses | median ms | worst ms | best ms | worst pose "
                  "| visibility median / worst ms | CPU record / pipelined frame ms (median) "
                  "| top passes (median ms) | primary_rays stages (median ms) | frame shows (median over poses) "
                  "| frame shows (worst pose) |",
                  "|" + "---|" * 16]
        for s in (s for s in summary if s["scene"] == scene):
            top = ", ".join(f"{k} {v:.3f}" for k, v in list(s["passes"].items())[:TOP_PASSES])
            stages = ", ".join(f"{k} {v:.3f}" for k, v in s.get("primary_stages", {}).items()) or "-"
            lines.append(f"| {s['config']} | {s['variant']} | {s['camera']} | {s['primary']} | {s['msaa']} | "
                         f"{s['poses']} | {s['median_ms']:.3f} | {s['worst_ms']:.3f} | {s['best_ms']:.3f} | "
                         f"{s['worst_pose_label']} | "
                         f"{s['visibility_median_ms']:.3f} / {s['visibility_worst_ms']:.3f} | "
                         f"{loop_cell(s)} | {top} | {stages} | {share_text(s['effect_share'])} | "
                         f"{share_text(s['worst_effect_share'])} |")
        lines.append("")
        rounds = [(s, round_totals(worst_row(rows, s))) for s in summary if s["scene"] == scene]
        if any(ms for _, ms in rounds):
            lines += ["Rounds of the worst pose (the passes that run once a round, summed, ms, in the order run; "
                      "a channel set's last round shades every pixel, the others only the pixels with that "
                      "many distinct triangles):", ""]
            lines += [f"- {s['config']} {s['variant']} {s['camera']} {s['msaa']}x: " + ", ".join(f"{v:.3f}" for v in ms)
                      + f" (pose {s['worst_pose']}, {s['worst_pose_kind']})" for s, ms in rounds if ms]
            lines.append("")
        counted = [(s, worst_row(rows, s)) for s in summary if s["scene"] == scene]
        if any(w.get("rays") for _, w in counted):
            lines += ["Rays of the worst pose, counted on the GPU in one more frame (every round), and each "
                      "pass's rays per second at its timed ms:", ""]
            lines += [f"- {s['config']} {s['variant']} {s['camera']} {s['msaa']}x, pose {s['worst_pose']} rays: "
                      f"{rays_text(w['rays'], w.get('effect_share'))}" for s, w in counted if w.get("rays")]
            lines.append("")
        judged = [t for t in targets(rows, meta["per_eye_size"]) if t["scene"] == scene]
        if judged:
            lines += ["Targets, on the worst pose (over the poses and configs measured):", "",
                      "| target | bound | variant | worst | pose (kind), config | met |", "|---|---|---|---|---|---|"]
            for t in judged:
                unit = " GRays/s" if t["target"] == "primary_rate" else ("x" if "frame" in t["target"] else " ms")
                lines.append(f"| {t['target']} | {t['what']} | {t['variant']} | {t['worst']:.3f}{unit} | "
                             f"{t.get('worst_pose_label', t['worst_pose'])}, {t['worst_config']} | "
                             f"{'yes' if t['met'] else 'NO'} |")
            lines.append("")
    chosen = meta.get("primary_choices") or {}
    if len({r["variant"] for r in rows}) > 1 and chosen:
        lines += ["## Primary visibility: the fastest variant per camera model and MSAA count", "",
                  "The worst `primary_rays` pass (the only pass the knobs change) over every scene, config and pose "
                  "measured; "
                  + (f"{CHOICES_FILE} holds the choices (copy it to rayvr/assets/ for the renderer to take them)."
                     if meta.get("timings_meaningful", True) else
                     f"a software rasterizer's timings say nothing: no {CHOICES_FILE} written."), "",
                  "| camera model | MSAA | chosen | its knobs | worst primary_rays ms per variant |",
                  "|---|---|---|---|---|"]
        for model, counts in chosen.items():
            for msaa, c in counts.items():
                knobs = ", ".join(f"{k}={v}" for k, v in c["knobs"].items())
                per = ", ".join(f"{v} {ms:.3f}" for v, ms in sorted(c["worst_ms"].items(), key=lambda kv: kv[1]))
                lines.append(f"| {model} | {msaa} | {c['variant']} | {knobs} | {per} |")
        lines.append("")
    return "\n".join(lines) + "\n"


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), poses=POSES, pose_seed=POSE_SEED,
        cameras=CAMERAS, counts=COUNTS, configs=DEFAULT_CONFIGS, variants=None, budget_ms=BUDGET_MS,
        repeat=10, warmup=3, quick=False, backend=None, progress=True, gl=None) -> dict:
    """Time the grid (cells) on `poses` head poses of each of `scenes` into `out_dir` (vr.json, vr.md).
    `variants`: {name: RenderSettings fields} added to every row's settings (default VARIANTS); `gl`:
    a context to render on (default: a new one from `backend`, released at the end)."""
    from tqdm import tqdm

    variants = checked_variants(variants)
    checked_grid(cameras, counts, configs)
    if poses < 1:
        raise ValueError(f"bench vr --poses must be at least 1, got {poses}")
    grid = cells(cameras, counts, configs, variants)
    out = Path(out_dir)
    t_start = time.perf_counter()
    own = gl is None
    gl = gl or create_context(backend)
    rows, skipped = [], {}
    try:
        meta = {**device_meta(gl.info()), "bench": "vr", "per_eye_size": list(size), "quick": quick,
                "poses": poses, "pose_seed": pose_seed, "pose_scheme": POSE_SCHEME, "repeat": repeat,
                "warmup_frames": warmup,
                "configs": list(configs), "variants": variants, "cameras": list(cameras), "counts": list(counts),
                "budget_ms": budget_ms, "timings_meaningful": not gl.is_software, "skipped": skipped,
                "what_times_include": f"median GPU ms (GL timer queries per pass, summed over a frame's rounds) "
                                      f"over {repeat} frames of both eyes, after a warm-up until frame times settle "
                                      f"(at least {WARMUP_S} s on each cell's first pose, {SCENE_WARMUP_S} s on a scene's "
                                      f"first); no readback",
                "scenes": {}, "seconds": 0.0}
        kept, kept_meta = kept_rows(out / "vr.json", meta, {(s, c) for s in scenes for c in configs})
        meta["scenes"].update(kept_meta)
        if kept:
            which = sorted({f"{r['scene']}/{r['config']}" for r in kept})
            meta["kept_rows"] = f"{len(kept)} rows ({', '.join(which)}) from the folder's earlier vr.json"

        def write() -> None:
            meta["seconds"] = time.perf_counter() - t_start
            meta["targets"] = targets(kept + rows, size)  # (write_report keeps meta and rows)
            chosen = primary_choices(kept + rows)
            meta["primary_choices"] = chosen
            result = {"meta": meta, "rows": kept + rows}
            write_report(out, "vr", result, md=markdown(result))
            # a choice among variants, timed on a GPU (a software rasterizer's timings say nothing)
            if len({r["variant"] for r in kept + rows}) > 1 and chosen and meta["timings_meaningful"]:
                text = json.dumps(choices_file(chosen, meta, out), indent=1) + "\n"
                atomic_write_bytes(out / CHOICES_FILE, text.encode())

        for name, scene, view in bench_scenes(scenes, size, skipped):
            heads = draw_poses(scene, name, poses, pose_seed)
            earlier = meta["scenes"].get(name, {})  # what the configs kept from the earlier run were
            sm = meta["scenes"][name] = {"region": region(name).what, "pose_bounds": pose_bounds(scene, name),
                                         "ipd": view.ipd, "fov_y": view.fov_y, "near": view.near,
                                         "configs": {c: v for c, v in earlier.get("configs", {}).items()
                                                     if c not in configs},
                                         "configs_skipped": {}, "cells_skipped": {},
                                         "poses": [p.to_dict() for p in heads]}
            mats = {}
            for config in configs:
                mats[config], about = materials_config(gl, config, name, scene, view, budget_ms, progress)
                sm["configs" if mats[config] is not None else "configs_skipped"][config] = about
            todo = [c for c in grid if mats[c[0]] is not None]
            shares = {}  # (config, camera, pose index) -> frame_share: the variants and counts see the same view
            bar = tqdm(total=len(todo) * len(heads), desc=f"vr {name}", unit="frame", disable=not progress)
            with Renderer(scene, gl=gl) as r:
                for cell_index, (config, variant, camera, msaa) in enumerate(todo):
                    model, fov, primary = CAMERA_CONFIGS[camera]
                    r.set_materials(mats[config])
                    r.settings = RenderSettings(primary=primary, msaa=msaa, **variants[variant])
                    try:
                        plan = r.plan(camera=model)
                    except ValueError as e:  # the renderer refuses the cell (ssr through a lens): say so, go on
                        sm["cells_skipped"][f"{config} {variant} {camera} {msaa}x"] = str(e)
                        bar.update(len(heads))
                        continue
                    for head in heads:
                        rig = StereoRig(head.pose, ipd=view.ipd, fov_y=fov or view.fov_y, near=view.near, size=size,
                                        camera=model)
                        first = SCENE_WARMUP_S if cell_index == 0 else WARMUP_S
                        timed = frame_row(r, rig, repeat, warmup, first if head.index == 0 else 0.0)
                        seen = (config, camera, head.index)
                        if seen not in shares:  # after the timed frames, apart from them
                            shares[seen] = frame_share(r, rig, mats[config])
                        rows.append({"scene": name, "pose": head.to_dict(), "config": config, "variant": variant,
                                     "camera": camera, "camera_model": model.name, "primary": primary, "msaa": msaa,
                                     "variant_fields": variants[variant], "tile_culling": plan.tile_culling,
                                     "tile_lists": plan.tile_lists, "block_culling": plan.block_culling,
                                     "tile_size": "x".join(map(str, plan.tile_pixels)),
                                     "tile_entries": plan.tile_entries, "block_tiles": plan.block_tiles, **timed,
                                     "effect_share": shares[seen]})
                        bar.update(1)
                    cell = [x["frame_ms"] for x in rows[-len(heads):]]
                    bar.write(f"  {name:8s} {config:8s} {variant:10s} {camera:20s} {msaa:2d}x frame median "
                              f"{np.median(cell):.3f} ms, worst {max(cell):.3f}, best {min(cell):.3f}")
                    write()
            bar.close()
        write()
    finally:
        if own:
            gl.release()
    return {"meta": meta, "rows": kept + rows}
