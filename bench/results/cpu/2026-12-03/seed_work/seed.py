# Traversal work (GPU-counted node fetches, tile entry tests, triangle tests; device-independent) of 4x sub-rays
# on Sponza at 240x264 (one eye, bench head poses of seed 22, tile-culled bvh2 from each tile's entries), with a hit seed
# (tmax at a known hit) against none: "perfect" = each ray's own closest hit, "central" = the pixel's central ray's triangle.
import sys, numpy as np
sys.path.insert(0, '.')
from rayvr.bench.scenes import load_bench_scene
from rayvr.bench.head_poses import draw_poses
from rayvr.frame.cameras.rig import StereoRig
from rayvr.accel.frustum import tile_order
from rayvr.accel.gpu import GpuBvh, RayTracer, MISS
from rayvr.accel.scene import build_scene_bvh
from rayvr.gl.context import create_context
import rayvr.bench.scenes as bs
bs.SHARED_SCENES = __import__('pathlib').Path('../shared/scenes')
name = sys.argv[1] if len(sys.argv) > 1 else 'sponza'
scene, _ = load_bench_scene(name)
W, H, N = 240, 264, 4
heads = draw_poses(scene, name, 3, 22)
gl = create_context()
bvh = build_scene_bvh(scene)
bvh = bvh[0] if isinstance(bvh, tuple) else bvh
rt = RayTracer(gl.ctx, GpuBvh(gl.ctx, bvh))
tris = bvh.triangles().astype(np.float64) if hasattr(bvh, 'triangles') else None
for head in heads:
    rig = StereoRig.for_scene(scene, size=(W, H)); rig.pose = head.pose
    eye = rig.eyes()[0]
    order = tile_order(W, H)
    def rays(sub):
        r = rig.camera.rays(eye, 0, subsample=sub)
        o = (np.broadcast_to(r.origins, (H, W, 3))[::-1] - scene.origin).reshape(-1, 3)[order]
        d = r.directions[::-1].reshape(-1, 3)[order]
        return o.astype(np.float32), d.astype(np.float32)
    oc, dc = rays(None)
    hc = rt.trace(oc, dc, tiles=True)
    tot = {}
    for i in range(N):
        o, d = rays((i, N))
        ref_w = {}; h = rt.trace(o, d, tiles=True, work=ref_w)
        t = h.t.astype(np.float64)
        # perfect seed: own closest distance
        tmax = np.where(h.prim != MISS, t * (1 + 1e-5), np.inf).astype(np.float32)
        ow = {}; h2 = rt.trace(o, d, tiles=True, tmax=tmax, work=ow)
        # realistic seed: the central ray's triangle, intersected by this sub-ray (numpy Moller-Trumbore)
        slot = hc.slot if hasattr(hc, 'slot') else None
        prim_c = hc.prim
        seed = np.full(len(o), np.inf)
        ok = prim_c != MISS
        V = bvh.triangles_by_id(prim_c[ok]) if hasattr(bvh, 'triangles_by_id') else None
        if V is None:
            inv = np.empty(bvh.prim_ids.max() + 1, np.int64); inv[bvh.prim_ids] = np.arange(len(bvh.prim_ids))
            V = bvh.triangles()[inv[prim_c[ok]]].astype(np.float64)
        oo, dd = o[ok].astype(np.float64), d[ok].astype(np.float64)
        e1, e2 = V[:, 1] - V[:, 0], V[:, 2] - V[:, 0]
        p = np.cross(dd, e2); det = (e1 * p).sum(1)
        tv = oo - V[:, 0]; u = (tv * p).sum(1) / det; q = np.cross(tv, e1); v = (dd * q).sum(1) / det
        tt = (e2 * q).sum(1) / det
        hit = (u >= 0) & (v >= 0) & (u + v <= 1) & (tt > 0)
        s = np.where(hit, tt * (1 + 1e-5), np.inf); seed[ok] = s
        sw = {}; h3 = rt.trace(o, d, tiles=True, tmax=seed.astype(np.float32), work=sw)
        for k, w in (("ref", ref_w), ("perfect", ow), ("central", sw)):
            a = tot.setdefault(k, np.zeros(3))
            a += [w['node_visits'].sum(), w['entry_tests'].sum(), w['triangle_tests'].sum()]
        tot.setdefault('seed_hit', 0); tot['seed_hit'] += hit.sum() / len(o) / N
    r = tot['ref']
    print(name, head.index, 'ref per ray nodes %.1f entries %.1f tris %.1f' % tuple(r / (W * H * N)),
          ' '.join(f"{k}: {tot[k].sum() / r.sum():.2f} (n {tot[k][0]/r[0]:.2f} e {tot[k][1]/r[1]:.2f} t {tot[k][2]/r[2]:.2f})" for k in ('perfect', 'central')),
          'seed hits %.2f' % tot['seed_hit'])
