"""`rayvr bench rays`: BVH build, GPU rays/s against Embree on the same rays, and a full stereo
hybrid frame with per-pass GPU ms.

Per scene (the benchmark views of rayvr/bench/scenes.py, both eyes of the stereo rig):
  build     binned-SAH build time (numpy, host), SAH cost, nodes, depth
  primary   the rig's camera rays (coherent), closest hit
  shadow    from each primary hit (barycentric point, offset_ray) to the scene's first point or
            rect light (or along its directional light), any hit
  reflect   mirror reflection of each primary ray at its hit (geometric normal), closest hit:
            incoherent secondary rays
  glossy_R  a GGX reflection of each primary ray at its hit, roughness R in GLOSSY_ROUGHNESS
            (visible normals sampled as Heitz 2018 describes, alpha = R^2; a direction under the
            surface reflected back over it, as the glossy effect does), closest hit
  diffuse   a cosine-weighted bounce from each primary hit, closest hit: path tracing's rays
  area_shadow  from each primary hit to a uniform random point of the scene's first rect light
            (none without one), any hit: the soft shadows' rays
The sampled kinds draw from RAY_SEED: every variant traces the same rays.
GPU rays/s come from GL timer queries around `repeat` dispatches of rayvr/glsl/accel/trace_rays.comp
with the rays already on the GPU, after a warm-up until times settle.

Traversal variants (`VARIANTS`, picked with `layouts` and `tiles`), each on the same rays of each
kind: `bvh2` (the binary child-pair nodes, the reference), `bvh2+tiles` (tile frustum culling: the
cull dispatch plus the trace from the tiles' entry lists, accel/frustum.py), `bvh4`/`bvh8` (wide
quantized nodes, nearest-first for closest and any hits) and their `-unordered` forms (timed on closest-hit
rays only), and `cwbvh` (the compressed 8-wide BVH of Ylitie et al. 2017, accel/cwbvh.py: octant-ordered
children, no sort). Layouts with GPU work counters (bvh2, cwbvh) also report `node_fetches_per_ray`
and `triangle_tests_per_ray` (means over the rays, counted in a separate dispatch of the same rays;
None for bvh4/bvh8, whose traversal has no counters). The camera rays are listed tile by tile (16 x 8 pixel blocks,
frustum.tile_order), and so are the secondary rays made from their hits; `bvh2 rows` traces the
primary rays in row order, as runs before the variants did. `agree_with_bvh2` is the fraction of
rays with the reference's triangle (or occlusion); `speedup_vs_bvh2` its rays/s ratio; `best` in
the meta names the fastest variant per ray kind and scene. Embree (embreex, one scene per process, a fork pool over every host
core) traces the same float32 rays; its time is the wall time of the pool's map after a warm-up.
Agreement with Embree (same triangle / same occlusion) is reported beside the speeds.
`builds` (`--bvh-build sah,sbvh`) runs every variant on each build's BVH (variants of builds after
the first are named "sbvh:bvh2", ...; rows carry `bvh_build`, `references` and `sah_cost`): SAH vs
spatial splits (accel/sbvh.py) per layout and ray kind, on the same rays.

The hybrid frame renders the scene with `shadows` on every material and mirror `reflections` on
the reflective ones (MIRRORS), through the Renderer's frame graph: raster G-buffer, classify,
per-effect passes by indirect dispatch, tonemap. Per-pass GPU ms are medians over `repeat` frames
after a warm-up; `effect_kernel_ms` splits the effect passes into their wavefront kernels (shading
vs tracing, medians of 5 more frames timed kernel by kernel).
Sponza (no MTL) is split into its OBJ groups by the loader; its mirror config is the `floors`
group, about 28 % of the pixels of the benchmark view.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import time

import numpy as np

from ..accel.bvh import offset_ray
from ..accel.frustum import tile_order
from ..accel.gpu import MISS, GpuBvh, RayTracer
from ..accel.scene import build_scene_bvh
from ..gl.context import create_context
from ..scene.materials import parse_config
from ..renderer import Renderer, RenderSettings
from ..gl.gpu_layout import TILE_ENTRIES, TILE_RAYS
from .report import device_meta, write_report
from .scenes import bench_scenes

# Reflective materials of each benchmark scene: mirror reflections in the hybrid frame.
MIRRORS = {"default": ("mirror*", "gold"), "sponza": ("floors",)}


def hybrid_config(name: str, mirrors: str = "reflections"):
    """Shadows on every material, the scene's MIRRORS on one bounce of `mirrors` (reflections: the
    BVH; ssr: the depth quadtree first, the BVH where the screen cannot answer)."""
    return parse_config({"default": "shadows",
                         "materials": {m: {"effect": mirrors, "bounces": 1} for m in MIRRORS.get(name, ())}},
                        f"bench:{name}")


# The wavefront frames timed per wavefront variant (--ray-order, --persistent): the hybrid frame, and
# with variants asked for, every material glossy or path traced (incoherent bounce and shadow rays).
INCOHERENT_FRAMES = {"glossy": {"effect": "glossy", "samples": 4, "bounces": 1},
                     "path": {"effect": "path", "bounces": 2}}


def frame_configs(name: str, incoherent: bool) -> dict:
    out = {"hybrid": hybrid_config(name)}
    if incoherent:
        out.update({k: parse_config({"default": "raster", "materials": {"*": v}}, f"bench:{name}:{k}")
                    for k, v in INCOHERENT_FRAMES.items()})
    return out


# (variant, layout, ordered closest hits, tile frustum culling)
VARIANTS = (("bvh2", "bvh2", True, False), ("bvh2+tiles", "bvh2", True, True),
            ("bvh4", "bvh4", True, False), ("bvh4-unordered", "bvh4", False, False),
            ("bvh8", "bvh8", True, False), ("bvh8-unordered", "bvh8", False, False),
            ("cwbvh", "cwbvh", True, False))
COUNTED_LAYOUTS = ("bvh2", "cwbvh")   # RayTracer.trace(work=) counts their traversal


def primary_rays(rig, origin, tiled: bool = False):
    """Both eyes' central camera rays of the rig's camera model (channel set 0), in GL rows
    (bottom-up) as the passes trace, or (`tiled`) listed tile by tile (frustum.tile_order) so that
    consecutive TILE_RAYS rays are a pixel block; a sample without a ray (foveated) gets a zero
    direction, traced as nothing."""
    o, d = [], []
    for eye in rig.eyes():
        r = rig.camera.rays(eye, 0)
        w, h = eye.size
        dirs = np.where(r.valid[..., None], r.directions, 0.0)[::-1].reshape(-1, 3)
        org = (np.broadcast_to(r.origins, (h, w, 3))[::-1] - origin).reshape(-1, 3)
        order = tile_order(w, h) if tiled else slice(None)
        o.append(org[order])
        d.append(dirs[order])
    return np.concatenate(o).astype(np.float32), np.concatenate(d).astype(np.float32)


def secondary_rays(scene, bvh, o, d, hits):
    """Shadow rays to the first light and mirror-reflected rays, from the primary hits."""
    h = np.flatnonzero(hits.prim != MISS)
    tri = scene.vertices[scene.indices[hits.prim[h]]].astype(np.float32)
    p = tri[:, 0] + hits.u[h, None] * (tri[:, 1] - tri[:, 0]) + hits.v[h, None] * (tri[:, 2] - tri[:, 0])
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    n *= -np.sign((n * d[h]).sum(1, keepdims=True))  # facing the eye
    n = n.astype(np.float32)
    light = next((l for l in scene.lights if l.kind in ("point", "rect")), None)
    if light is not None:
        target = (np.asarray(light.position) - scene.origin).astype(np.float32)
        sd = target - p
        side = np.where((sd * n).sum(1, keepdims=True) >= 0, n, -n)
        so = offset_ray(p, side)
        sd, stmax = (target - so).astype(np.float32), np.float32(1.0 - 1e-4)
    else:
        l = -np.asarray(scene.lights[0].direction if scene.lights else (0, -1, 0), np.float32)
        so = offset_ray(p, np.where((n @ l)[:, None] >= 0, n, -n))
        sd, stmax = np.broadcast_to(l, p.shape).astype(np.float32), np.float32(3e38)
    rd = d[h] - 2 * (d[h] * n).sum(1, keepdims=True) * n
    out = {"shadow": (so, sd, stmax, "any"), "reflect": (offset_ray(p, n), rd.astype(np.float32), np.float32(3e38), "closest")}
    return {**out, **sampled_rays(scene, p, n, d[h])}


GLOSSY_ROUGHNESS = (0.1, 0.3, 0.6)
RAY_SEED = 7
# every kind run() measures (--configs picks some; area_shadow only in a scene with a rect light)
RAY_KINDS = ("primary", "shadow", "reflect", *(f"glossy_{r:g}" for r in GLOSSY_ROUGHNESS), "diffuse", "area_shadow")


def _basis(n):
    """Two unit tangents (t, b) completing each unit normal n to a right-handed frame."""
    a = np.where(np.abs(n[:, :1]) > 0.9, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    t = np.cross(a, n)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(n, t)


def ggx_visible_normals(v_local, alpha, u1, u2):
    """Microfacet normals (local frame, z up) of GGX width alpha seen from v_local, drawn in
    proportion to their visible area (Heitz 2018: the view stretched to the unit hemisphere, a
    point of its projected disk lifted onto it, stretched back)."""
    vh = np.stack([alpha * v_local[:, 0], alpha * v_local[:, 1], v_local[:, 2]], 1)
    vh /= np.linalg.norm(vh, axis=1, keepdims=True)
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    t1 = np.where(lensq[:, None] > 0, np.stack([-vh[:, 1], vh[:, 0], np.zeros_like(lensq)], 1)
                  / np.sqrt(np.maximum(lensq, 1e-30))[:, None], np.array([[1.0, 0.0, 0.0]]))
    t2 = np.cross(vh, t1)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    a, b = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])
    b = (1.0 - s) * np.sqrt(np.maximum(1.0 - a * a, 0.0)) + s * b
    nh = a[:, None] * t1 + b[:, None] * t2 + np.sqrt(np.maximum(1.0 - a * a - b * b, 0.0))[:, None] * vh
    m = np.stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(nh[:, 2], 0.0)], 1)
    return m / np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-30)


def sampled_rays(scene, p, n, d):
    """The sampled secondary kinds from hit points p (geometric normals n facing the eye, camera
    directions d): glossy reflections at GLOSSY_ROUGHNESS, a diffuse bounce, area-light shadows."""
    rng = np.random.default_rng(RAY_SEED)
    n64, d64 = n.astype(np.float64), d.astype(np.float64) / np.linalg.norm(d, axis=1, keepdims=True)
    t, b = _basis(n64)
    o = offset_ray(p, n)
    out = {}
    v = -d64
    v_local = np.stack([(v * t).sum(1), (v * b).sum(1), np.maximum((v * n64).sum(1), 1e-4)], 1)
    for rough in GLOSSY_ROUGHNESS:
        m_local = ggx_visible_normals(v_local, max(rough * rough, 1e-3), rng.random(len(p)), rng.random(len(p)))
        m = m_local[:, :1] * t + m_local[:, 1:2] * b + m_local[:, 2:] * n64
        l = d64 - 2 * (d64 * m).sum(1, keepdims=True) * m
        under = (l * n64).sum(1, keepdims=True) <= 0
        l = np.where(under, l - 2 * (l * n64).sum(1, keepdims=True) * n64, l)
        out[f"glossy_{rough:g}"] = (o, l.astype(np.float32), np.float32(3e38), "closest")
    r, phi = np.sqrt(rng.random(len(p))), 2 * np.pi * rng.random(len(p))
    z = np.sqrt(np.maximum(1.0 - r * r, 0.0))
    bounce = (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * b + z[:, None] * n64
    out["diffuse"] = (o, bounce.astype(np.float32), np.float32(3e38), "closest")
    rect = next((li for li in scene.lights if li.kind == "rect"), None)
    if rect is not None:
        st = rng.uniform(-1.0, 1.0, (len(p), 2))
        q = (np.asarray(rect.position) - scene.origin) + st[:, :1] * np.asarray(rect.u) + st[:, 1:] * np.asarray(rect.v)
        to = q - p
        side = np.where((to * n64).sum(1, keepdims=True) >= 0, n, -n)
        so = offset_ray(p, side)
        out["area_shadow"] = (so, (q - so).astype(np.float32), np.float32(1.0 - 1e-4), "any")
    return out


# -------------------------------------------------------------------------- Embree, all cores

_WORK: dict = {}


def _embree_init():
    from embreex import mesh_construction, rtcore_scene
    s = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(s, _WORK["vertices"], _WORK["indices"])
    _WORK["scene"] = s


def _embree_chunk(job):
    """Trace rays [lo, hi) of a kind already in this worker; returns the hits and the seconds the
    trace call itself took (no pool dispatch, no transfer of the results)."""
    kind, lo, hi = job
    o, d, tmax, mode = _WORK["rays"][kind]
    dists = np.full(hi - lo, tmax, np.float32)
    t0 = time.perf_counter()
    if mode == "any":
        hits = _WORK["scene"].run(o[lo:hi], d[lo:hi], dists=dists, query="OCCLUDED") != -1
    else:
        hits = _WORK["scene"].run(o[lo:hi], d[lo:hi], dists=dists)
    return lo, hits, time.perf_counter() - t0


def embree_trace(pool, workers, kind, n, repeat=1):
    """(hits, wall seconds, trace seconds): wall is the whole parallel map, results back in this
    process included (the rays are in the workers before timing); trace is the busiest worker's
    time inside Embree's calls (embreex traces ray by ray: rtcIntersect1, no packets/streams)."""
    chunk = max(1, -(-n // (workers * 8)))
    jobs = [(kind, s, min(n, s + chunk)) for s in range(0, n, chunk)]
    best, best_trace = np.inf, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        parts = pool.map(_embree_chunk, jobs)
        best = min(best, time.perf_counter() - t0)
        # Chunks are handed out in order to `workers` processes: the ideal spread of the tracing.
        best_trace = min(best_trace, sum(p[2] for p in parts) / workers)
    out = np.concatenate([r for _, r, _ in sorted(parts, key=lambda x: x[0])])
    return out, best, best_trace


# -------------------------------------------------------------------------- the run

def time_frame(renderer, rig, repeat, warmup, warmup_s=0.3):
    """Median GPU ms per pass and of the frame total over `repeat` frames, after a warm-up of at
    least `warmup` frames and `warmup_s` seconds that lasts until frame times settle."""
    names, ms = None, {}
    renderer.warm_up(rig, seconds=warmup_s, min_frames=warmup)
    for i in range(repeat):
        fc = renderer.record(rig, "both", "color")
        renderer.gl.ctx.finish()
        t = renderer.read_ms(fc)
        names = fc.pass_names
        for k, v in t.items():
            ms.setdefault(k, []).append(v)
    med = {k: float(np.median(v)) for k, v in ms.items()}
    totals = np.sum([ms[k] for k in ms], axis=0)
    return names, med, float(np.median(totals))


PIPELINED_FRAMES = 20  # frames a render loop records back to back in time_pipelined


def time_pipelined(renderer, rig, frames: int = PIPELINED_FRAMES) -> dict:
    """What a render loop meets beside the GPU's passes: `frames` frames recorded back to back, then
    one finish. `record_ms`: the median CPU time of one frame's recording; `pipelined_ms`: the wall
    time a frame over the loop. Where the CPU records slower than the GPU runs (small frames of many
    MSAA rounds) the GPU waits for commands, inside whichever pass's timer window is open: then the
    passes' sum overstates the GPU's work, and the pipelined time is the frame rate
    (bench/results/h200/2026-12-03/final/bubble)."""
    renderer.gl.ctx.finish()
    spent = []
    start = time.perf_counter()
    for _ in range(frames):
        t0 = time.perf_counter()
        renderer.record(rig, "both", "color")
        spent.append(time.perf_counter() - t0)
    renderer.gl.ctx.finish()
    wall = time.perf_counter() - start
    return {"record_ms": float(np.median(spent)) * 1e3, "pipelined_ms": wall / frames * 1e3}


def time_stages(renderer, rig, prefix: str, repeat=5) -> dict:
    """Median GPU ms over `repeat` frames timed kernel by kernel (GL timer queries) of each kernel of
    the passes whose names start with `prefix` ("rt_shadows.shadow", ...), summed over a frame's rounds."""
    ms: dict = {}
    for _ in range(repeat):
        fc = renderer.record(rig, "both", "color", profile=True)
        for name, v in renderer.read_ms(fc).items():
            if name.startswith(prefix) and "." in name:
                ms.setdefault(name, []).append(v)
    return {k: float(np.median(v)) for k, v in ms.items()}


def time_effect_stages(renderer, rig, repeat=5) -> dict:
    """Median GPU ms of each kernel of the wavefront effect passes ("rt_shadows.shadow", ...)."""
    return time_stages(renderer, rig, "rt_", repeat)


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), repeat=20, warmup=3, workers=None,
        backend=None, progress=True, layouts=("bvh2", "bvh4", "bvh8", "cwbvh"), tiles: bool = True,
        builds=("sah",), kinds=None, wavefront=None) -> dict:
    """`layouts` and `tiles` pick the traversal variants (VARIANTS); bvh2 is always measured (the
    reference every variant is compared with). `builds` (bvh.BUILDS): each variant runs on a BVH of
    each build; the first build's bvh2 is the reference (rays, agreement, speedups, Embree).
    `kinds`: the ray kinds to time (RAY_KINDS; None: all). `wavefront`: {name: RenderSettings
    fields} (--ray-order, --persistent): each wavefront frame is timed with each; given, the
    incoherent frames (INCOHERENT_FRAMES) are timed too. The batch ray kinds above are traced by
    accel/gpu.py RayTracer, not the wavefront: these options do not reach them."""
    layouts = tuple(dict.fromkeys(("bvh2",) + tuple(layouts)))
    builds = tuple(dict.fromkeys(builds))
    workers = workers or os.cpu_count() or 1
    variants = [v for v in VARIANTS if v[1] in layouts and (tiles or not v[3])]
    gl = create_context(backend)
    rows, frames, skipped, best = [], [], {}, {}
    try:
        for name, scene, rig in bench_scenes(scenes, size, skipped):
            bvhs = {b: build_scene_bvh(scene, b, progress=progress) for b in builds}
            gpus = {}
            for b in builds:
                for layout in dict.fromkeys(v[1] for v in variants):
                    t0 = time.perf_counter()
                    gpus[b, layout] = GpuBvh(gl, bvhs[b], layout=layout)
                    gpus[b, layout].pack_s = time.perf_counter() - t0
            bvh = bvhs[builds[0]]
            rt = RayTracer(gl, gpus[builds[0], "bvh2"])
            o, d = primary_rays(rig, scene.origin, tiled=True)
            hits = rt.trace(o, d)
            rays = {"primary": (o, d, np.float32(3e38), "closest"), **secondary_rays(scene, bvh, o, d, hits)}
            rays = {k: v for k, v in rays.items() if kinds is None or k in kinds}
            base = {b: {"scene": name, "triangles": scene.triangle_count, "bvh_build": b,
                        "references": x.reference_count, "build_s": x.build_seconds, "sah_cost": x.sah_cost(),
                        "gpu_nodes": x.gpu_node_count, "max_depth": x.max_depth} for b, x in bvhs.items()}
            _WORK.update(vertices=np.ascontiguousarray(scene.vertices, np.float32),
                         indices=np.ascontiguousarray(scene.indices, np.int32), rays=rays)
            try:
                import embreex  # noqa: F401
                pool = mp.get_context("fork").Pool(workers, initializer=_embree_init)
                pool.map(_embree_chunk, [("primary", 0, 1)] * workers)  # every worker built its scene
            except ImportError:
                pool = None
            try:
                for kind, (ro, rd, tmax, mode) in rays.items():
                    reference = rt.trace(ro, rd, tmax=tmax, mode=mode)
                    ref_prim = reference if mode == "any" else reference.prim
                    runs = [(b, v, ro, rd) for b in builds for v in variants
                            if not (mode == "any" and v[0].endswith("-unordered"))]
                    if kind == "primary" and "bvh2" in layouts:
                        rows_o, rows_d = primary_rays(rig, scene.origin)
                        runs.insert(1, (builds[0], ("bvh2 rows", "bvh2", True, False), rows_o, rows_d))
                    ref_rate = None
                    for b, (variant, layout, ordered, tiled), vo, vd in runs:
                        vrt = RayTracer(gl, gpus[b, layout], ordered=ordered)
                        g = vrt.time_trace(vo, vd, tmax=tmax, mode=mode, repeats=repeat, tiles=tiled)
                        work = {} if layout in COUNTED_LAYOUTS else None
                        mine = vrt.trace(vo, vd, tmax=tmax, mode=mode, tiles=tiled, work=work)
                        mine = mine if mode == "any" else mine.prim
                        agree = float((mine == ref_prim).mean()) if variant != "bvh2 rows" else None
                        ref_rate = ref_rate or g["rays_per_s"]
                        w = gpus[b, layout].wide
                        label = variant if b == builds[0] else f"{b}:{variant}"
                        row = {**base[b], "rays_kind": kind, "variant": label, "layout": layout, "ordered": ordered,
                               "tiles": tiled, "ray_order": "rows" if variant == "bvh2 rows" else "tiles16x8",
                               "node_bytes": gpus[b, layout].nodes.size, "pack_s": gpus[b, layout].pack_s,
                               "wide_nodes": w.node_count if w is not None else 0,
                               "rays": len(vo), "gpu_ms": g["gpu_ms"], "gpu_ms_min": g["gpu_ms_min"],
                               "gpu_ms_max": g["gpu_ms_max"], "cull_ms": g["cull_ms"],
                               "gpu_grays_s": g["rays_per_s"] / 1e9, "speedup_vs_bvh2": g["rays_per_s"] / ref_rate,
                               "agree_with_bvh2": agree,
                               "node_fetches_per_ray": float(work["node_visits"].mean()) if work else None,
                               "triangle_tests_per_ray": float(work["triangle_tests"].mean()) if work else None}
                        if pool is not None and label == "bvh2":
                            ref, secs, trace_secs = embree_trace(pool, workers, kind, len(ro), repeat=3)
                            if mode == "any":
                                eagree = float((reference == ref).mean())
                            else:
                                eagree = float((reference.prim == np.where(ref >= 0, ref, -1).astype(np.uint32)).mean())
                            row.update(embree_ms=secs * 1e3, embree_grays_s=len(ro) / secs / 1e9,
                                       speedup_vs_embree=(len(ro) / secs) and g["rays_per_s"] / (len(ro) / secs),
                                       embree_trace_ms=trace_secs * 1e3,
                                       speedup_vs_embree_trace=g["rays_per_s"] * trace_secs / len(ro),
                                       agree_with_embree=eagree)
                        rows.append(row)
                        key = f"{name}/{kind}"
                        if variant != "bvh2 rows" and row["gpu_grays_s"] > best.get(key, ("", 0.0))[1]:
                            best[key] = (label, row["gpu_grays_s"])
                        if progress:
                            print(f"  {name:8s} {kind:8s} {label:20s} {row['gpu_grays_s']:.3f} GRays/s GPU"
                                  f" ({row['speedup_vs_bvh2']:.2f}x bvh2" + (f", agree {agree:.4%})" if agree is not None else ")")
                                  + (f", {row['node_fetches_per_ray']:.1f} node fetches a ray" if work else "")
                                  + (f", Embree {row['embree_grays_s']:.3f} ({row['speedup_vs_embree']:.1f}x; "
                                     f"{row['speedup_vs_embree_trace']:.1f}x its trace calls alone),"
                                     f" agree {row['agree_with_embree']:.4%}" if "embree_ms" in row else ""))
            finally:
                if pool is not None:
                    pool.close()
                    pool.join()
                _WORK.clear()
                for g in gpus.values():
                    g.release()
            wave_variants = wavefront or {"default": {}}
            frame_grid = [(b, frame, cfg, v) for b in builds for frame, cfg in frame_configs(name, bool(wavefront)).items()
                          for v in wave_variants]
            for b, frame, cfg, variant in frame_grid:   # the wavefront frames on each build's BVH
                r = Renderer(scene, cfg, gl=gl, settings=RenderSettings(bvh_build=b, **wave_variants[variant]))
                try:
                    names, med, total = time_frame(r, rig, repeat, warmup)
                    stages = time_effect_stages(r, rig)
                    counts = r.pixel_counts()
                    pixels = 2 * size[0] * size[1]
                    frames.append({"scene": name, "bvh_build": b, "frame": frame, "wavefront": variant,
                                   "size": f"2x{size[0]}x{size[1]}", "passes": names,
                                   "pass_ms": {k: med[k] for k in names if k in med}, "total_ms": total,
                                   "mirror_pixel_fraction": counts.get("reflections", 0) / pixels,
                                   "shadow_pixel_fraction": counts.get("shadows", 0) / pixels,
                                   "effect_kernel_ms": stages,
                                   "config": {"default": "shadows", "reflections": list(MIRRORS.get(name, ()))}
                                   if frame == "hybrid" else {"*": INCOHERENT_FRAMES[frame]}})
                    if progress:
                        print(f"  {name:8s} {frame} frame ({b}, {variant}) {total:.3f} ms: "
                              + ", ".join(f"{k} {v:.3f}" for k, v in frames[-1]["pass_ms"].items()))
                        print(f"  {name:8s} effect kernels: " + ", ".join(f"{k} {v:.3f}" for k, v in stages.items()))
                finally:
                    r.release()
        meta = {**device_meta(gl.info()), "bench": "rays", "per_eye_size": list(size), "repeat": repeat,
                "host_cores": os.cpu_count(), "embree_workers": workers, "skipped": skipped,
                "variants": [v[0] for v in variants], "bvh_builds": list(builds),
                "tile_rays": TILE_RAYS, "tile_entries": TILE_ENTRIES,
                "best": {k: {"variant": v, "gpu_grays_s": r} for k, (v, r) in best.items()},
                "what_times_include": {
                    "gpu_ms": "GL timer query around the trace dispatches only (with tiles: the cull "
                              "dispatch too); rays and BVH already on the GPU, no upload or readback",
                    "cull_ms": "the tile cull dispatch alone (tiles variants)",
                    "embree_ms": "wall time of the parallel map over all host cores (embreex, one "
                                 "rtcIntersect1 per ray); rays already in the workers, hits sent back",
                    "embree_trace_ms": "time inside Embree's trace calls, summed over chunks and "
                                       "divided by the workers (perfect spread, no dispatch, no transfer)"},
                "hybrid_frames": frames}
    finally:
        gl.release()
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "rays", result)
    return result
