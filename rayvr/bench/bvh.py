"""`rayvr bench bvh`: the BVH builds (bvh.BUILDS: binned SAH, SBVH with spatial splits) compared on
the host, no GPU needed: build time, triangle references per triangle, SAH cost, and the traversal
work per ray that the numpy reference traversal counts on a sample of each ray kind.

Per scene (the benchmark views of bench/scenes.py) and build:
  build     seconds (numpy, this host), references / triangles, SAH cost, nodes, depth
  primary   `samples` rays drawn (fixed seed) from both eyes' camera rays at `size`, closest hit
  shadow    from their hits to the scene's light, any hit (bench rays' secondary_rays)
  reflect   mirror reflections at their hits, closest hit
For each kind: mean child-pair node fetches per ray (`pair_node_visits`: what the GPU bvh2 layout
fetches), one-box node visits, triangle tests, and the same for the bvh4 layout's numpy walk (its
children in slot order, not nearest first, so an upper bound of the GPU's ordered walk); and the
fraction of rays whose hit (triangle, or occlusion) equals the first build's: the builds must
agree (ties between coplanar triangles aside). GPU rays/s of the builds: `rayvr bench rays
--bvh-build sah,sbvh`.
"""
from __future__ import annotations

import time

import numpy as np
from tqdm import tqdm

from ..accel.gpu import Hits
from ..accel.bvh import trace_reference
from ..accel.scene import build_scene_bvh
from ..accel.wide import build_wide, trace_wide_reference
from .rays import primary_rays, secondary_rays
from .report import device_meta, write_report
from .scenes import bench_scenes

SEED = 1


def count_work(bvh, o, d, tmax, mode, wide=None) -> tuple[dict, np.ndarray]:
    """Mean traversal work per ray (numpy reference) and the hits (prim ids, or occlusion)."""
    st, wst = {}, {}
    res = trace_reference(bvh, o, d, tmax=tmax, any_hit=mode == "any", stats=st)
    out = {"pair_node_visits": float(st["pair_node_visits"].mean()), "node_visits": float(st["node_visits"].mean()),
           "triangle_tests": float(st["triangle_tests"].mean())}
    if wide is not None:
        trace_wide_reference(wide, o, d, tmax=tmax, any_hit=mode == "any", stats=wst)
        out.update(bvh4_node_visits=float(wst["node_visits"].mean()),
                   bvh4_triangle_tests=float(wst["triangle_tests"].mean()))
    return out, (res if mode == "any" else res[0])


def run(out_dir, size=(1440, 1600), scenes=("default", "sponza"), builds=("sah", "sbvh"), samples=4096,
        progress=True) -> dict:
    rows, skipped = [], {}
    scene_list = list(bench_scenes(scenes, size, skipped))
    bar = tqdm(total=len(scene_list) * len(builds), desc="bench bvh", disable=not progress)
    for name, scene, rig in scene_list:
        o_all, d_all = primary_rays(rig, scene.origin)
        pick = np.random.default_rng(SEED).choice(len(o_all), min(samples, len(o_all)), replace=False)
        o, d = o_all[np.sort(pick)], d_all[np.sort(pick)]
        rays, reference = None, {}
        for build in builds:
            bar.set_postfix_str(f"{name} {build}")
            bvh = build_scene_bvh(scene, build, progress=progress)
            t0 = time.perf_counter()
            wide = build_wide(bvh, 4)
            wide_s = time.perf_counter() - t0
            if rays is None:   # the first build's primary hits make every build's secondary rays
                prim, t, u, v = trace_reference(bvh, o, d)
                hits = Hits(prim, t.astype(np.float32), u.astype(np.float32), v.astype(np.float32))
                rays = {"primary": (o, d, np.float32(3e38), "closest"), **secondary_rays(scene, bvh, o, d, hits)}
            for kind, (ro, rd, tmax, mode) in rays.items():
                work, res = count_work(bvh, ro, rd, tmax, mode, wide)
                reference.setdefault(kind, res)
                rows.append({"scene": name, "triangles": bvh.triangle_count, "bvh_build": build,
                             "references": bvh.reference_count,
                             "references_per_triangle": bvh.reference_count / max(1, bvh.triangle_count),
                             "build_s": bvh.build_seconds, "bvh4_collapse_s": wide_s, "sah_cost": bvh.sah_cost(),
                             "nodes": bvh.node_count, "max_depth": bvh.max_depth,
                             "spatial_split_nodes": bvh.params.get("spatial_split_nodes", 0),
                             "rays_kind": kind, "rays": len(ro), **work,
                             "agree_with_first_build": float((res == reference[kind]).mean())})
            bar.update()
    bar.close()
    meta = {**device_meta(None), "bench": "bvh", "per_eye_size": list(size), "samples_per_kind": samples,
            "seed": SEED, "builds": list(builds), "skipped": skipped,
            "what_counts": {
                "pair_node_visits": "child-pair nodes (bvh2, the GPU layout) whose box the ray enters, per ray",
                "node_visits": "nodes popped by a one-box-per-node binary walk, per ray",
                "triangle_tests": "ray-triangle tests (leaf slots) per ray, binary walk",
                "bvh4_node_visits": "bvh4 nodes fetched per ray (numpy walk, children in slot order)",
                "build_s": "numpy build on this host (2 shared cores here), not the GPU machine"}}
    result = {"meta": meta, "rows": rows}
    write_report(out_dir, "bvh", result)
    return result
