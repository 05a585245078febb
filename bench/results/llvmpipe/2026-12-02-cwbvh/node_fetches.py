"""Node fetches and triangle tests per ray of every BVH layout (bvh2, bvh4, bvh8, cwbvh), and the
builds' times and sizes, on the host.

Per scene (the bench views of `rayvr bench rays`: the room, Sponza where the shared scenes folder
has it; and a soup of 262,144 random triangles, Sponza's size, for the build times):
  rays     the bench rays' kinds from both eyes at SIZE (primary, shadow to the first light,
           mirror reflection) and `random`: RANDOM_RAYS rays from inside the scene's bounds in
           uniformly random directions (incoherent closest hits; any hit within a tenth of the
           bounds' diagonal for `random_any`)
  numpy    each layout's numpy reference walk (bvh.trace_reference's `pair_node_visits` for the
           child-pair bvh2, wide.trace_wide_reference, cwbvh.trace_cwbvh_reference), checked to
           give the binary reference's hits; these visit children in stored order (left first,
           slot order), not nearest first as the GPU's bvh2/bvh4/bvh8 do; cwbvh's walk is its GPU
           order; `cwbvh slot order` is it with every ray in slot order (no octant order)
  gpu      the GLSL traversal's own counters (bvh.glsl BVH_COUNT_WORK; bvh2 and cwbvh have them)
           under llvmpipe, checked to give bvh2's hits bit for bit
The counts depend on the tree and the rays, not on the device.

    PYTHONPATH=. python bench/results/llvmpipe/2026-12-02-cwbvh/node_fetches.py [160x178]
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

from rayvr.accel.bvh import build_bvh, trace_reference
from rayvr.accel.cwbvh import NODE_COST, TRIANGLE_COST, build_cwbvh, trace_cwbvh_reference
from rayvr.accel.gpu import GpuBvh, RayTracer
from rayvr.accel.sah import _half_area
from rayvr.accel.scene import build_scene_bvh
from rayvr.accel.wide import build_wide, trace_wide_reference
from rayvr.bench.rays import primary_rays, secondary_rays
from rayvr.bench.scenes import bench_scenes
from rayvr.gl.context import create_context

HERE = Path(__file__).parent
RANDOM_RAYS = 20000
SOUP_TRIANGLES = 1 << 18


def sah_cost(child_lo, child_hi, used, leaf, leaf_count) -> float:
    """Σ node area x NODE_COST + Σ leaf child area x TRIANGLE_COST x triangles, over the root's area
    (the collapse's own cost, cwbvh.py), for any 8-wide tree given its child boxes."""
    lo, hi = child_lo.astype(np.float64), child_hi.astype(np.float64)
    node = _half_area(np.where(used[..., None], lo, np.inf).min(1), np.where(used[..., None], hi, -np.inf).max(1))
    return float((NODE_COST * node.sum() + TRIANGLE_COST * (_half_area(lo, hi)[leaf] * leaf_count[leaf]).sum())
                 / node[0])


def wide8_cost(w) -> float:
    b = w.bvh
    c = np.maximum(w.child, 0)
    used = w.child >= 0
    leaf = used & (b.left[c] < 0)
    return sah_cost(b.node_lo[c], b.node_hi[c], used, leaf, b.count[c])


def random_rays(v, n, seed=1):
    rng = np.random.default_rng(seed)
    lo, hi = v.min(0), v.max(0)
    o = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    return o, d, float(np.linalg.norm(hi - lo))


def builds(bvh):
    out, trees = {}, {}
    for width in (4, 8):
        t0 = time.perf_counter()
        trees[f"bvh{width}"] = build_wide(bvh, width)
        out[f"bvh{width}"] = {"build_s": time.perf_counter() - t0, "nodes": trees[f"bvh{width}"].node_count,
                              "node_bytes": trees[f"bvh{width}"].nbytes}
    cw = trees["cwbvh"] = build_cwbvh(bvh)
    out["cwbvh"] = {"build_s": cw.build_seconds, "nodes": cw.node_count, "node_bytes": cw.node_count * 80,
                    "buffer_bytes": cw.nbytes, "depth": int(cw.depth.max()),
                    "mean_children": cw.stats()["mean_children"]}
    out["bvh2"] = {"build_s": bvh.build_seconds, "nodes": bvh.gpu_node_count, "node_bytes": bvh.gpu_node_count * 64}
    lo, hi = cw.child_boxes()
    out["sah_cost"] = {"bvh8": wide8_cost(trees["bvh8"]),
                       "cwbvh": sah_cost(lo, hi, cw.kind != 0, cw.kind == 2, cw.tri_count)}
    return out, trees


def measure(gl, bvh, trees, o, d, tmax, mode):
    any_hit = mode == "any"
    row = {"rays": len(o)}
    st = {}
    ref = trace_reference(bvh, o, d, tmax=tmax, any_hit=any_hit, stats=st)
    ref_prim = ref if any_hit else ref[0]
    row["numpy"] = {"bvh2": {"node_fetches": float(st["pair_node_visits"].mean()),
                             "triangle_tests": float(st["triangle_tests"].mean())}}
    for name, tree in trees.items():
        st = {}
        walk = trace_cwbvh_reference if name == "cwbvh" else trace_wide_reference
        got = walk(tree, o, d, tmax=tmax, any_hit=any_hit, stats=st)
        assert np.array_equal(got if any_hit else got[0], ref_prim), f"{name}: numpy walk differs from bvh2"
        row["numpy"][name] = {"node_fetches": float(st["node_visits"].mean()),
                              "triangle_tests": float(st["triangle_tests"].mean())}
    st = {}
    trace_cwbvh_reference(trees["cwbvh"], o, d, tmax=tmax, any_hit=any_hit, stats=st, octant_order=False)
    row["numpy"]["cwbvh slot order"] = {"node_fetches": float(st["node_visits"].mean()),
                                        "triangle_tests": float(st["triangle_tests"].mean())}
    row["gpu"] = {}
    hits = {}
    for layout in ("bvh2", "cwbvh"):
        g = GpuBvh(gl.ctx, bvh, layout=layout)
        work = {}
        hits[layout] = RayTracer(gl.ctx, g).trace(o, d, tmax=tmax, mode=mode, work=work)
        g.release()
        row["gpu"][layout] = {"node_fetches": float(work["node_visits"].mean()),
                              "triangle_tests": float(work["triangle_tests"].mean())}
    a, b = hits["bvh2"], hits["cwbvh"]
    same = np.array_equal(a, b) if any_hit else (np.array_equal(a.prim, b.prim) and np.array_equal(a.t.view(np.uint32), b.t.view(np.uint32)))
    assert same, "cwbvh GPU hits differ from bvh2"
    row["gpu_same_hits_as_bvh2"] = same
    return row


def main():
    size = tuple(int(x) for x in (sys.argv[1] if len(sys.argv) > 1 else "160x178").split("x"))
    gl = create_context()
    skipped, rows = {}, []
    out = (HERE / "node_fetches.jsonl").open("w")

    def emit(row):
        rows.append(row)
        out.write(json.dumps(row) + "\n")
        out.flush()
        print(json.dumps(row), flush=True)

    for name, scene, rig in bench_scenes(("default", "sponza"), size, skipped):
        bvh = build_scene_bvh(scene, progress=False)
        info, trees = builds(bvh)
        emit({"scene": name, "triangles": scene.triangle_count, "builds": info})
        o, d = primary_rays(rig, scene.origin, tiled=True)
        hits = RayTracer(gl.ctx, GpuBvh(gl.ctx, bvh)).trace(o, d)
        kinds = {"primary": (o, d, np.float32(3e38), "closest"), **secondary_rays(scene, bvh, o, d, hits)}
        ro, rd, diag = random_rays(np.asarray(scene.vertices, np.float32), RANDOM_RAYS)
        kinds["random"] = (ro, rd, np.float32(3e38), "closest")
        kinds["random_any"] = (ro, rd / np.linalg.norm(rd, axis=1, keepdims=True), np.float32(0.1 * diag), "any")
        for kind, (ko, kd, tmax, mode) in kinds.items():
            emit({"scene": name, "rays_kind": kind, "size": f"2x{size[0]}x{size[1]}", "mode": mode,
                  **measure(gl, bvh, trees, ko, kd, tmax, mode)})
    rng = np.random.default_rng(0)
    v = (rng.uniform(-50, 50, (SOUP_TRIANGLES, 1, 3)) + rng.normal(size=(SOUP_TRIANGLES, 3, 3))).reshape(-1, 3)
    v = v.astype(np.float32)
    f = np.arange(3 * SOUP_TRIANGLES).reshape(-1, 3)
    bvh = build_bvh(v, f)
    info, trees = builds(bvh)
    emit({"scene": "soup", "triangles": SOUP_TRIANGLES, "builds": info})
    ro, rd, _ = random_rays(v, RANDOM_RAYS)
    emit({"scene": "soup", "rays_kind": "random", "mode": "closest", **measure(gl, bvh, trees, ro, rd, np.float32(3e38), "closest")})
    print("skipped", skipped)


if __name__ == "__main__":
    main()
