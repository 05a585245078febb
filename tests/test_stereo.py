"""Stereo modes beyond `dual` (rayvr/frame/stereo.py): `reuse` (frame/passes/reuse.py) and `warp`
(frame/passes/warp.py), each against `dual` on the same frame and against an independent reference:
the numpy reuse map, the central view, mirror symmetry."""
from dataclasses import replace

import numpy as np
import pytest

from conftest import merge, quad, run_rayvr
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.graph import FramePlan, compile_graph
from rayvr.frame.passes.reuse import read_map, reference_map
from rayvr.frame.passes.warp import read_holes
from rayvr.renderer import Renderer, RenderSettings, candidate_passes
from rayvr.scene.loader import from_arrays

SIZE = (64, 48)
ROOM = "rayvr/assets/default_room.toml"
STEREO_PASSES = {"reuse_map", "reuse_copy", "warp"}


@pytest.fixture(scope="module")
def room(gl):
    with Renderer(None, ROOM, gl=gl) as r:
        yield r


@pytest.fixture(scope="module")
def raster_room(gl):
    with Renderer(None, None, gl=gl) as r:  # raster only: deterministic, view-dependent specular
        yield r


def render(r, mode, rig, **kw):
    r.set_stereo(mode)
    try:
        return r.render(rig, **kw)
    finally:
        r.set_stereo("dual")


def mean_abs(a, b) -> float:
    return float(np.abs(a.astype(int) - b.astype(int)).mean())


@pytest.mark.parametrize("effects", [frozenset({"raster"}), frozenset({"shadows", "reflections", "glossy", "ssr"})])
def test_graph_compiles_only_what_the_mode_needs(effects):
    names = {m: set(compile_graph(candidate_passes(p), p).pass_names)
             for m, p in ((m, FramePlan(effects=effects, stereo=m, eyes=1 if m == "warp" else 2,
                                        output="stereo_ldr" if m == "warp" else "ldr"))
                          for m in ("dual", "warp", "reuse"))}
    assert not names["dual"] & STEREO_PASSES
    assert names["reuse"] - names["dual"] == {"reuse_map", "reuse_copy"}
    assert names["warp"] - names["dual"] <= {"warp", "quadtree"} and "warp" in names["warp"]
    assert "quadtree" in names["warp"]
    if "ssr" not in effects:
        assert "quadtree" not in names["dual"]


def test_one_eye_and_debug_views_stay_dual(room):
    room.set_stereo("reuse")
    try:
        assert room.plan(eyes=1).stereo == "dual"
        assert not STEREO_PASSES & set(room.compiled(room.plan(view="normal")).pass_names)
    finally:
        room.set_stereo("dual")
    with pytest.raises(ValueError, match="unknown stereo mode"):
        room.set_stereo("mono")


def test_reuse_ipd0_identical_eyes_and_no_right_pixel_shaded(room):
    rig = StereoRig.for_scene(room.scene, size=SIZE, ipd=0.0)
    f = render(room, "reuse", rig, aux=("hdr",))
    assert np.array_equal(f.left.color, f.right.color)
    assert np.isfinite(f.left.aux["hdr"]).all() and np.isfinite(f.right.aux["hdr"]).all()
    counts = room.stereo_counts()
    covered = int((f.right.depth > 0).sum())
    # Every covered right pixel takes the left one's shading, but for float rounding at pixel edges.
    assert covered - 4 <= counts["reused"] <= covered
    lists = room.pixel_counts()
    dual = render(room, "dual", rig)
    assert np.array_equal(dual.left.color, f.left.color)
    dual_lists = room.pixel_counts()
    # The traced effects' lists hold the left eye and the few right pixels not taken (dual: both eyes).
    assert all(dual_lists[e] // 2 <= lists[e] <= dual_lists[e] // 2 + covered - counts["reused"] for e in lists)


def test_reuse_map_equals_numpy_and_lists_skip_taken_pixels(room):
    rig = StereoRig.for_scene(room.scene, size=SIZE)
    f = render(room, "reuse", rig, aux=("position", "normal", "material", "triangle", "effect"))
    fc = room._last
    gpu = read_map(fc)
    ref = reference_map(f.left, f.right, rig.eye("left"), rig.eye("right"))
    assert (gpu >= 0).sum() > 0.8 * (f.right.depth > 0).sum()
    assert (gpu == ref).mean() >= 0.995, (gpu != ref).sum()
    # No right-eye pixel is both taken and in a traced effect's list; every other traced one is listed.
    from rayvr.frame.passes.classify import list_slots
    args = np.frombuffer(room.resource("rt_list_args").read(16 * list_slots()), np.uint32).reshape(-1, 4)
    packed = np.frombuffer(room.resource("rt_lists").read(), np.uint32)
    cap = SIZE[0] * SIZE[1] * 2
    listed = np.zeros((SIZE[1], SIZE[0]), int)
    for slot, (_, _, _, n) in enumerate(args):
        v = packed[slot * cap: slot * cap + n]
        v = v[(v >> 28) == 1]
        np.add.at(listed, (SIZE[1] - 1 - ((v >> 14) & 0x3FFF), v & 0x3FFF), 1)
    from rayvr.frame.effects import traced_effects
    traced = np.isin(f.right.aux["effect"], [e.id for e in traced_effects()])
    assert listed.max() <= 1
    assert not (listed.astype(bool) & (gpu >= 0)).any()
    assert np.array_equal(listed.astype(bool), traced & (gpu < 0))


def test_reuse_shades_no_taken_pixel(gl):
    """Without the copy, a taken right-eye pixel keeps what the HDR target held before: neither
    `shade` nor a traced effect wrote it."""
    from rayvr.frame.graph import FrameGraph
    with Renderer(None, ROOM, gl=gl) as r:
        r.graph = FrameGraph(gl, lambda plan: [p for p in candidate_passes(plan) if p.name != "reuse_copy"])
        r.settings.background = (1.0, 0.0, 1.0)
        rig = StereoRig.for_scene(r.scene, size=SIZE)
        away = StereoRig(Pose.look_at(r.scene.center + [0, 0, 1e4], r.scene.center + [0, 0, 2e4]), size=SIZE)
        bg = render(r, "reuse", away).right.color[0, 0]  # every pixel background: magenta in the HDR target
        r.settings.background = (0.0, 0.0, 0.0)
        f = render(r, "reuse", rig)
        taken = read_map(r._last) >= 0
        magenta = np.all(f.right.color == bg, axis=-1)
        assert bg[0] > 200 and bg[1] < 50 and bg[2] > 200
        assert taken.sum() > 100
        assert magenta[taken].all()
        assert not magenta[~taken].any()


def test_reuse_gives_no_shading_to_a_surface_the_right_eye_sees_from_behind(gl):
    """A quad whose plane passes between the eyes (x = 0, eyes at x = -/+ 0.5): the left eye sees
    its lit side, the right eye its unlit back (two-sided, so its G-buffer shows the same triangle
    in the same plane and material: only "faces the right eye", tested with the right eye's
    position, refuses the landing). Its right-eye pixels shade themselves, as under `dual`;
    the wall behind, which both eyes see from the front, is reused."""
    from rayvr.scene.loader import Light, Material

    quad_v, quad_f = quad((0.0, 0.0, -1.9), (0.0, 0.0, 1.1), (0.0, 0.6, 0.0))
    wall_v, wall_f = quad((0.0, 0.0, -4.0), (4.0, 0.0, 0.0), (0.0, 3.0, 0.0))
    v, f, part = merge((quad_v, quad_f), (wall_v, wall_f))
    scene = from_arrays(v, f, triangle_material=part, materials=[Material("fin"), Material("wall")],
                        lights=[Light("point", intensity=3.0, position=(-1.5, 0.3, -1.5))], ambient_lights=False)
    rig = StereoRig(Pose.look_at([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]), ipd=1.0, fov_y=60, size=SIZE)
    with Renderer(scene, None, gl=gl) as r:
        dual = render(r, "dual", rig, aux=("triangle",))
        reuse = render(r, "reuse", rig, aux=("triangle", "position", "normal", "material"))
        taken = read_map(r._last) >= 0
    fin_left = dual.left.aux["triangle"] < 2
    fin_right = reuse.right.aux["triangle"] < 2
    assert fin_left.sum() > 20 and fin_right.sum() > 20
    lit, unlit = dual.left.color[fin_left].mean(), dual.right.color[fin_right].mean()
    assert lit > unlit + 40  # a copy of the left's shading would show
    assert not taken[fin_right].any()
    assert np.abs(reuse.right.color[fin_right].astype(int) - dual.right.color[fin_right].astype(int)).max() <= 2
    wall = reuse.right.aux["triangle"] >= 2
    assert taken[wall].mean() > 0.3  # (the part of it the left eye sees too)
    ref = reference_map(reuse.left, reuse.right, rig.eye("left"), rig.eye("right"))
    assert not (ref[fin_right] >= 0).any()


def test_reuse_small_ipd_error_bound(raster_room):
    rig = StereoRig.for_scene(raster_room.scene, size=SIZE, ipd=0.02)
    dual, reuse = render(raster_room, "dual", rig), render(raster_room, "reuse", rig)
    assert np.array_equal(dual.left.color, reuse.left.color)
    assert np.array_equal(dual.right.depth, reuse.right.depth)
    # Copied view-dependent shading (specular) and a half-pixel resampling: small.
    assert mean_abs(dual.right.color, reuse.right.color) < 1.5


def test_warp_ipd0_equals_the_central_view(room):
    rig = StereoRig.for_scene(room.scene, size=SIZE, ipd=0.0)
    central = render(room, "dual", rig)  # IPD 0: both eyes are the central view
    f = render(room, "warp", rig)
    for eye in ("left", "right"):
        assert np.array_equal(f[eye].color, central[eye].color)
        # Each eye's ray is the central pixel's, its depth computed as the G-buffer resolve does
        # (that ray's crossing of the pixel's triangle): equal but for a GPU compiler contracting
        # multiply-adds differently in two programs (ulps). Taken from the hit's point in S it was
        # off by up to 5e-6 here, 1.4e-3 at 320x240 and 4.5e-4 on an H200 (issue 20).
        np.testing.assert_allclose(f[eye].depth, central[eye].depth, rtol=1e-6)
    c = room.stereo_counts()
    assert c["disoccluded_left"] == c["offscreen_left"] == c["disoccluded_right"] == c["offscreen_right"] == 0


def test_warp_small_ipd_error_bound_and_holes_counted(raster_room):
    rig = StereoRig.for_scene(raster_room.scene, size=SIZE, ipd=0.02)
    dual, warp = render(raster_room, "dual", rig), render(raster_room, "warp", rig)
    c = raster_room.stereo_counts()
    holes = read_holes(raster_room._last)
    for i, eye in enumerate(("left", "right")):
        assert mean_abs(dual[eye].color, warp[eye].color) < 2.0
        d = np.abs(dual[eye].depth - warp[eye].depth)
        both = (dual[eye].depth > 0) & (warp[eye].depth > 0)
        assert np.median(d[both] / dual[eye].depth[both]) < 1e-3
        assert np.isfinite(warp[eye].depth).all()
        assert holes[i].sum() == c[f"disoccluded_{eye}"] + c[f"offscreen_{eye}"]
        assert c[f"hole_fraction_{eye}"] < 0.01
    assert c["hits_left"] > 0 and c["nodes_right"] > 0
    render(raster_room, "warp", rig)
    assert raster_room.stereo_counts() == c  # the counts start from zero every frame


def longest_row_run(mask: np.ndarray) -> int:
    """The longest run of True along any row of a 2-D mask."""
    best = 0
    for row in mask:
        edges = np.diff(np.concatenate([[0], row.astype(np.int8), [0]]))
        starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
        best = max(best, int((ends - starts).max(initial=0)))
    return best


@pytest.mark.parametrize("size", [(96, 72), (320, 240)], ids=["96x72", "320x240"])
def test_warp_writes_no_streaks_beside_depth_edges(raster_room, size):
    """Against `dual`, pixel by pixel: a warped pixel may be wrong only in a disocclusion, whose
    width along a row is at most the disparity between the central view and the eye (half the
    IPD, at the nearest depth). Leaf planes made from the room's smooth-shaded box's shading
    normals swept a whole pixel column towards the camera at its silhouette: before hits were
    kept near a discontinuity's sample only, rays in front of the box "hit" them, drawing bars
    ~20 px long at 64x48 from its top and bottom edges (issue 20); and they disagreed ~4 % at
    shared edges of one face, so at 320x240 the left eye's rays slipped between them: a dark
    line 13 px long across the box's top, gone since the leaves are the triangles' planes."""
    rig = StereoRig.for_scene(raster_room.scene, size=size)
    dual, warp = render(raster_room, "dual", rig), render(raster_room, "warp", rig)
    left = rig.eye("left")
    kx = rig.size[0] / (left.tangents[1] - left.tangents[0])  # pixels per unit tangent
    for eye in ("left", "right"):
        d, w = dual[eye].depth, warp[eye].depth
        assert (d > 0).mean() > 0.9
        disparity = kx * (rig.ipd / 2) / d[d > 0].min()  # pixels between the central view and the eye
        wrong_depth = np.abs(w - d) > 0.05 * np.maximum(d, w)
        wrong_color = np.abs(warp[eye].color.astype(int) - dual[eye].color.astype(int)).max(-1) > 48
        for wrong in (wrong_depth, wrong_color):
            assert longest_row_run(wrong) <= np.ceil(disparity) + 2, (eye, longest_row_run(wrong), disparity)
        assert wrong_depth.mean() < 0.02  # disocclusions and the column the central view does not see


def test_warp_traversal_equals_numpy_where_leaves_are_steep(raster_room):
    """The GPU warp against the numpy mirror (accel/quadtree.py trace_layers, and its brute force)
    on the rows where the room's central view has steep leaves at discontinuities: the same holes,
    and hits at the same depth; and no hit more than twice nearer than its leaf's sample. Leaves
    made from the box's shading normals had such hits (the streaks' cause, issue 20); the
    triangles' own planes reach no further than their pixel's surface."""
    from rayvr.accel import quadtree as qt
    from rayvr.frame.passes.warp import THICKNESS

    size = (96, 72)
    rig = StereoRig.for_scene(raster_room.scene, size=size)
    warp = render(raster_room, "warp", rig)
    fc = raster_room._last
    holes = read_holes(fc)
    per_layer = qt.level_offsets(qt.level_sizes(*size))[1]
    flat = np.frombuffer(fc.resource("quadtree").read(), np.uint32).reshape(-1, 2)
    trees = [qt.unflatten(flat[i * per_layer:(i + 1) * per_layer], size) for i in range(2)]
    center = rig.eye("center")
    cam = qt.ScreenCamera.from_eye(center, raster_room.scene.origin)
    leaves = qt.decode(trees[0][0])
    steep = leaves.flag & (np.abs(leaves.sx) > 0.08)  # > 8 % of z per pixel
    rows = np.unique(np.nonzero(steep)[0])[:4]  # GL rows
    assert len(rows) >= 2
    far_off_hits = rays_traced = gpu_agrees = brute_agrees = 0
    for i, eye in enumerate(rig.eyes()):
        rays = eye.rays()
        for gy in rows:
            y = size[1] - 1 - gy
            for x in range(size[0]):
                o, d = rays.origins[y, x] - raster_room.scene.origin, rays.directions[y, x]
                a = qt.trace_layers(trees, cam, o, d, THICKNESS)
                b = qt.trace_layers_brute_force([t[0] for t in trees], cam, o, d, THICKNESS)
                rays_traced += 1
                brute_agrees += (a.status, a.layer, a.pixel) == (b.status, b.layer, b.pixel)
                # The eyes are offset across the central view's axis: a hit's depth is near / z in both.
                depth = center.near / a.point[2] if a.status == qt.HIT else 0.0
                # (the GPU takes a hit's depth from its triangle, within the slab of the S point)
                gpu_agrees += (holes[i, y, x] == (a.status in (qt.OCCLUDED, qt.OFFSCREEN, qt.NEAR)) and
                               (a.status != qt.HIT or abs(warp[eye.name].depth[y, x] - depth) <= 1.01 * THICKNESS * depth))
                if a.status == qt.HIT and a.layer == 0:
                    far_off_hits += a.point[2] > 2 * qt.decode(trees[0][0][a.pixel[1], a.pixel[0]]).z0
    assert gpu_agrees >= 0.99 * rays_traced, (gpu_agrees, rays_traced)  # float32 ties at pixel edges aside
    # Two layers' planes crossing inside a pixel order them differently (tests/test_quadtree_layers.py).
    assert brute_agrees >= 0.95 * rays_traced, (brute_agrees, rays_traced)
    assert far_off_hits == 0


def symmetric_scene():
    v, f, _ = merge(quad((0, 0, -6), (5, 0, 0), (0, 5, 0)), quad((-1.0, 0, -3.0), (0.4, 0, 0), (0, 1.5, 0)),
                    quad((1.0, 0, -3.0), (0.4, 0, 0), (0, 1.5, 0)), quad((0, 0, -2.0), (0.3, 0, 0), (0, 0.3, 0)))
    return from_arrays(v, f)


def test_warp_holes_are_disocclusions_and_symmetric(gl):
    """One depth layer: rays that pass behind a surface of the central view are holes, beside its
    depth discontinuities, mirror-symmetric between the eyes. Two layers: those pixels become hits
    on the second layer, at the depth and in the colour the eye's own (dual) render has there."""
    scene = symmetric_scene()
    rig = StereoRig(Pose.look_at([0, 0, 0.5], [0, 0, -5]), ipd=0.3, fov_y=60, size=(63, 41))
    with Renderer(scene, None, gl=gl, settings=RenderSettings(warp_layers=1)) as r:
        central = render(r, "dual", replace(rig, ipd=0.0))
        dual = render(r, "dual", rig)
        warp = render(r, "warp", rig)
        holes = read_holes(r._last)
        c = r.stereo_counts()
        r.settings.warp_layers = 2
        warp2 = render(r, "warp", rig)
        holes2 = read_holes(r._last)
        c2 = r.stereo_counts()
    assert c["disoccluded_left"] > 0 and c["disoccluded_right"] > 0
    # Left/right symmetry: the mirrored left eye is the right eye (holes and depth).
    assert abs(int(holes[0].sum()) - int(holes[1].sum())) <= 2
    assert (holes[0][:, ::-1] == holes[1]).mean() > 0.995
    dl, dr = warp.left.depth[:, ::-1], warp.right.depth
    assert (np.abs(dl - dr) <= 1e-3 * np.maximum(dl, 1e-9)).mean() > 0.98
    # Mirror symmetry holds with the eyes swapped too: each warped eye must be its own eye, its
    # depth the eye's own (dual) depth, also wherever the two eyes differ (by the disparity,
    # beside every depth edge). Swapped, those pixels match 0 % and all seen pixels 77 %.
    for i, (eye, other) in enumerate((("left", "right"), ("right", "left"))):
        d, w = dual[eye].depth, warp[eye].depth
        differ = np.abs(d - dual[other].depth) > 0.05 * np.maximum(d, dual[other].depth)
        seen = ~holes[i]
        same = np.abs(w - d) <= 1e-2 * np.maximum(d, 1e-9)
        assert (differ & seen).sum() > 20
        # (a one-pixel column at each silhouette lands on either side: the half-pixel resampling)
        assert same[differ & seen].mean() > 0.9 and same[seen].mean() > 0.95
    # Holes are rays that passed behind a surface of the central view: beside one of its depth
    # discontinuities (a nearer and a farther surface, or a surface and the background, within
    # the disparity of a few pixels).
    d = central.left.depth
    for i in range(2):
        ys, xs = np.nonzero(holes[i])
        for y, x in zip(ys, xs):
            w = d[y, max(x - 3, 0):x + 4]
            assert w.min() == 0 < w.max() or w.max() > 1.2 * w.min(), (i, y, x, w)
    # The second layer answers them: fewer holes, and where the one-layer warp had a hole behind a
    # surface the two-layer warp sees what the eye sees (depth and colour of the eye's own render).
    assert holes2.sum() < holes.sum() and c2["hits_second_layer_left"] > 0
    for i, eye in enumerate(("left", "right")):
        seen = holes[i] & (dual[eye].depth > 0)  # the eye sees a surface there; else the background
        m = seen & ~holes2[i]
        assert m.sum() >= 0.8 * seen.sum() > 0
        assert (warp2[eye].depth[holes[i] & ~seen] == 0).mean() >= 0.8
        np.testing.assert_allclose(warp2[eye].depth[m], dual[eye].depth[m], rtol=1e-3)
        assert np.abs(warp2[eye].color[m].astype(int) - dual[eye].color[m].astype(int)).max() <= 2
        assert np.isfinite(warp[eye].depth).all() and np.isfinite(warp2[eye].depth).all()


def warp_outcomes(eye_sign, half_ipd, tau, depth_f, depth_b, slab):
    """Per column of an eye at x = eye_sign * half_ipd (tangents `tau`) over two fronto-parallel
    planes, F at depth_f covering x < 0 and B at depth_b covering x > 0 of the central view (at
    the origin, looking down -z): (hole, within a slab, depth of the surface it lands on) by the
    slab rule of docs/stereo.md. The ray's central-view tangent is e / depth + tau: it enters the
    image through the border on its eye's side at depth e / (+-1 - tau), over that side's plane,
    and crosses to the other side's plane at depth -e / tau. Over each plane in turn: entering it
    deeper than its depth, it is behind it there: a hole if deeper than depth / (1 - slab), else it
    takes the plane's sample; entering in front and leaving deeper, it hits the plane."""
    e = eye_sign * half_ipd
    own, other = (depth_b, depth_f) if eye_sign > 0 else (depth_f, depth_b)
    hole = np.zeros(len(tau), bool)
    in_slab = np.zeros(len(tau), bool)
    depth = np.zeros(len(tau))
    for i, t in enumerate(tau):
        enter = e / (eye_sign - t)
        cross = -e / t if t * eye_sign < 0 else np.inf
        for surface, a, b in ((own, enter, cross), (other, cross, np.inf)):
            if a > surface:
                hole[i], in_slab[i], depth[i] = a > surface / (1 - slab), a <= surface / (1 - slab), surface
                break
            if b > surface:
                depth[i] = surface
                break
    return hole, in_slab, depth


def test_warp_slab_thickness_alone_decides_which_rays_behind_a_surface_are_holes(gl):
    """The warp's threshold, as docs/stereo.md states it: each surface of the central view is a slab
    2 % deep in S's z (near / depth); a ray entering a surface's pixels deeper than that behind it
    passed behind it (a hole, with one depth layer), one within it takes its sample. Two
    fronto-parallel planes, F at depth 1 covering x < 0 (its edge on the central image's middle
    pixel boundary) and B at depth 2 covering x > 0, seen by eyes ~0.8 either side of the centre,
    with tangents -1..1 across 4096 x 2 pixels: no ray leaves the central image, and each either
    hits a plane or enters a plane's pixels already behind it, at a depth known in closed form
    (warp_outcomes), through the image border or across F's edge. The holes are the columns where
    that depth is more than 1 / 0.98 of the plane's, in both eyes exactly; the columns within a
    slab (33, and 16 more in the right eye) land on its plane, at its depth. Fails if the slab is
    1 % or 4 % (THICKNESS in frame/passes/warp.py; the thickness warp.comp traces with, halved or
    doubled), if qt_cell (ssrt/quadtree.glsl) compares the depth behind with 2 % absolute instead
    of 2 % of z, or with 2 % of the ray's z (a slab 2 % deep in depth: its back 0.6 px off here)."""
    slab = 0.02                                   # docs/stereo.md: "a slab 2 % deep in z"
    W, H, depth_f, depth_b = 4096, 2, 1.0, 2.0
    half_ipd = 1606 / (W / 2) / (1 - slab)        # ~0.8: the slabs' backs fall on pixel edges
    v, f, _ = merge(quad((-1.5, 0, -depth_f), (1.5, 0, 0), (0, 0.5, 0)),     # F: x in [-3, 0]
                    quad((1.5, 0, -depth_b), (1.5, 0, 0), (0, 1, 0)))       # B: x in [0, 3]
    rig = StereoRig(Pose.look_at([0, 0, 0], [0, 0, -1]), ipd=2 * half_ipd, size=(W, H),
                    fov_y=float(np.degrees(2 * np.arctan(H / W))))
    with Renderer(from_arrays(v, f), None, gl=gl, settings=RenderSettings(warp_layers=1)) as r:
        warp = render(r, "warp", rig)
        holes = read_holes(r._last)
        c = r.stereo_counts()
    tau = (np.arange(W) + 0.5) / W * 2 - 1        # column tangents (x / depth)
    for i, (eye, sign) in enumerate((("left", -1), ("right", 1))):
        assert np.allclose(rig.eye(eye).tangents, (-1, 1, -H / W, H / W))
        hole, in_slab, depth = warp_outcomes(sign, half_ipd, tau, depth_f, depth_b, slab)
        for nudge in (-0.1, 0.1):                 # no ray within 0.1 px of where its outcome flips
            assert np.array_equal(warp_outcomes(sign, half_ipd, tau + nudge * 2 / W, depth_f, depth_b, slab)[0], hole)
        # within F's slab 0.02 x 0.8 of tangent: 33 columns (both eyes); within B's (right eye) 16 more
        assert in_slab.sum() == {"left": 33, "right": 49}[eye] and hole.sum() > 1000
        assert np.array_equal(holes[i], np.broadcast_to(hole, (H, W))), (eye, np.flatnonzero(holes[i][0] != hole))
        assert c[f"disoccluded_{eye}"] == hole.sum() * H and c[f"offscreen_{eye}"] == 0
        seen = np.broadcast_to(~hole, (H, W))
        np.testing.assert_allclose(warp[eye].depth[seen], np.broadcast_to(depth, (H, W))[seen], rtol=1e-5)


def test_cli_stereo(tmp_path):
    run = run_rayvr
    p = run("capture", "--stereo", "warp", "--size", "32x24", "--out", str(tmp_path), "-q")
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "frame_left.png").exists() and (tmp_path / "frame_right.png").exists()
    p = run("capture", "--stereo", "reuse", "--view", "normal", "--size", "32x24", "--out", str(tmp_path), "-q")
    assert p.returncode == 0, p.stderr  # a debug view has no shading to reuse: the mode changes nothing
    p = run("capture", "--stereo", "warp", "--aux", "normal", "--size", "32x24", "--out", str(tmp_path), "-q")
    assert p.returncode == 2 and "warp" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    p = run("capture", "--stereo", "warp", "--format", "exr", "--out", str(tmp_path))
    assert p.returncode == 2 and "exr" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    p = run("capture", "--stereo", "triple", "--out", str(tmp_path))
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1


def test_preview_b_key_cycles_the_stereo_mode():
    from rayvr.app.preview import Camera, Controls, ViewState

    rig = StereoRig(Pose.look_at([0.0, 0.0, 5.0], [0.0, 0.0, 0.0]), size=(64, 48))
    c = Controls(Camera(rig, center=(0.0, 0.0, 0.0), extent=2.0), ViewState())
    seen = []
    for _ in range(3):
        c.key("B", "press")
        c.key("B", "release")
        seen.append(c.state.method)
    assert seen == ["warp", "reuse", "dual"]
    c.key("B", "press", shift=True)
    assert c.state.method == "reuse"


@pytest.mark.parametrize("mode", ["warp", "reuse"])
def test_tiled_frames_keep_the_stereo_mode(gl, mode):
    """A frame too large for the device renders in tiles; each tile is the same mode on an off-axis
    part of every eye's frustum (the central view's too): at IPD 0 the tiled eyes equal the whole
    frame's (but for rounding), and at a small IPD they differ only where a ray or a reused hit
    crossed a tile edge."""
    from rayvr.frame.graph import DeviceLimits

    with Renderer(None, None, gl=gl, settings=RenderSettings(stereo=mode)) as r:
        for ipd, bound in ((0.0, 0.01), (0.02, 1.5)):
            rig = StereoRig.for_scene(r.scene, size=(61, 45), ipd=ipd)
            r.graph.limits = DeviceLimits.of(gl)
            whole = r.render(rig)
            r.graph.limits = DeviceLimits(max_texture_size=32, max_ssbo_bytes=1 << 31, memory_bytes=None)
            assert len(r.tiles(rig)) == 4
            tiled = r.render(rig)
            for eye in ("left", "right"):
                assert mean_abs(whole[eye].color, tiled[eye].color) <= bound, (ipd, eye)
                if ipd == 0.0:  # the same rays: equal but for rounding
                    assert np.abs(whole[eye].color.astype(int) - tiled[eye].color.astype(int)).max() <= 2
            if ipd == 0.0:
                assert np.array_equal(tiled.left.color, tiled.right.color)
