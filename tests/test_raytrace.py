"""Ray-traced effects and primary visibility (frame/passes/trace_effect.py, classify.py, primary_rays.py, glsl/rt/): pass-graph pruning,
pixel lists, analytic mirrors, bounce counts, cross-checks against Embree, soft-shadow convergence.
Small images: these run on llvmpipe."""
from __future__ import annotations

import moderngl
import numpy as np
import pytest
import trimesh

from conftest import merge, quad, quick_bench, run_rayvr
from rayvr.accel.bvh import offset_ray
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.gbuffer import NO_HIT
from rayvr.scene.materials import EFFECTS, parse_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays, load

DARK = RenderSettings(ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0))


def render(gl, scene, rig, config=None, settings=None, aux=("triangle", "material", "position"), **renderer):
    """The frame, its HDR colour ((eyes, H, W, 3) float32, rows top-down) and the passes that ran;
    `renderer`: the Renderer's other keywords."""
    r = Renderer(scene, parse_config(config or {}, "test"), gl=gl, settings=settings or RenderSettings(), **renderer)
    try:
        frame = r.render(rig, aux=tuple(aux) + ("hdr",))
        hdr = np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]])
        return frame, hdr, r.compiled().passes
    finally:
        r.release()


def everything(effect, **params):
    """A config giving every material `effect` with `params`."""
    return {"default": effect, "params": {effect: params}}


def no_light():
    return [Light("point", intensity=0.0)]  # keeps emissive quads from becoming rect lights


def embree(verts, faces):
    pytest.importorskip("embreex")
    from embreex import mesh_construction, rtcore_scene
    s = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(s, np.asarray(verts, np.float32), np.asarray(faces, np.int32))
    return s


# ------------------------------------------------------------------------------ the graph

def test_all_raster_scene_builds_no_bvh_and_traces_nothing(gl, monkeypatch):
    import rayvr.accel.scene as accel_scene

    def refuse(scene):
        raise AssertionError("an all-raster frame built a BVH")
    monkeypatch.setattr(accel_scene, "build_scene_bvh", refuse)
    scene = load()
    rig = StereoRig.for_scene(scene, size=(24, 16))
    for view in ("color", "effect"):
        r = Renderer(scene, gl=gl)
        r.render(rig, view=view)
        names = set(r.compiled(r.plan(2, view)).pass_names)
        assert not names & {"bvh", "classify", "primary_rays", "rt_shadows", "rt_reflections", "rt_glossy"}, names
        assert not r.accel.built
        r.release()
    # A debug view of a traced config needs no rays either: the graph drops what the output ignores.
    r = Renderer(scene, parse_config({"default": "shadows"}, "t"), gl=gl)
    r.render(rig, view="normal")
    assert not r.accel.built
    r.release()


def test_renderers_of_the_same_geometry_build_its_bvh_once(gl, monkeypatch):
    """A process keeps the BVHs it built (accel/scene.py kept_scene_bvh): the next Renderer of the
    same triangles and build reuses one instead of building again; its own refit does not reach
    the kept one (a later Renderer of the unmoved scene sees the same triangles as the first);
    other positions or another build are built anew."""
    from collections import OrderedDict

    import rayvr.accel.scene as accel_scene

    builds = []
    real = accel_scene.build_scene_bvh

    def counting(scene, build="sah", progress=True):
        builds.append(build)
        return real(scene, build, progress=False)
    monkeypatch.setattr(accel_scene, "build_scene_bvh", counting)
    monkeypatch.setattr(accel_scene, "_kept", OrderedDict())
    scene = load()
    rig = StereoRig.for_scene(scene, size=(24, 16))
    first, _, _ = render(gl, scene, rig, {"default": "shadows"})
    assert builds == ["sah"]
    original = scene.vertices.copy()
    with Renderer(scene, parse_config({"default": "shadows"}, "t"), gl=gl) as r:
        again = r.render(rig, aux=("triangle",))
        r.update_vertices(original + np.float32([0.05, 0.0, 0.0]))  # refits this Renderer's copy
        assert not np.array_equal(r.render(rig, aux=("triangle",)).left.aux["triangle"], first.left.aux["triangle"])
    scene.vertices = original  # update_vertices moved the shared Scene's too
    assert builds == ["sah"] and np.array_equal(again.left.aux["triangle"], first.left.aux["triangle"])
    later, _, _ = render(gl, scene, rig, {"default": "shadows"})
    assert builds == ["sah"] and np.array_equal(later.left.aux["triangle"], first.left.aux["triangle"])
    other = from_arrays(original * np.float32(1.5), scene.indices, name="bigger")
    render(gl, other, StereoRig.for_scene(other, size=(24, 16)), {"default": "shadows"})
    render(gl, scene, rig, {"default": "shadows"}, settings=RenderSettings(bvh_build="sbvh"))
    assert builds == ["sah", "sah", "sbvh"]


def test_traced_effects_schedule_only_their_passes_and_list_their_pixels(gl):
    scene = load()
    rig = StereoRig.for_scene(scene, size=(40, 30))
    r = Renderer(scene, parse_config({"default": "raster", "materials": {"mirror*": "reflections",
                                                                        "walls": "shadows"}}, "t"), gl=gl)
    frame = r.render(rig, aux=("effect",))
    names = r.compiled().pass_names
    i = names.index
    assert i("bvh") < i("rt_shadows") and i("classify") < i("rt_shadows") and i("shade") < i("rt_shadows")
    assert i("rt_shadows") < i("tonemap") and i("rt_reflections") < i("tonemap")
    assert "rt_glossy" not in names and "primary_rays" not in names
    counts = r.pixel_counts()
    effect = np.stack([frame.left.aux["effect"], frame.right.aux["effect"]])
    for name in ("shadows", "reflections", "glossy"):
        assert counts[name] == int((effect == EFFECTS[name].id).sum())
    assert counts["shadows"] > 50 and counts["reflections"] > 10
    r.release()


def test_config_changes_the_image_only_on_the_configured_materials(gl):
    scene = load()
    rig = StereoRig.for_scene(scene, size=(48, 36))
    base, hdr0, _ = render(gl, scene, rig)
    for cfg, names in (({"materials": {"mirror*": {"effect": "reflections", "bounces": 2}}}, ("mirror", "mirror_panel")),
                       ({"materials": {"floor": {"effect": "glossy", "samples": 2}}}, ("floor",)),
                       ({"materials": {"box_*": "shadows", "walls": "shadows"}}, ("box_blue", "box_white", "walls"))):
        frame, hdr1, _ = render(gl, scene, rig, cfg)
        ids = [scene.material_names().index(n) for n in names]
        mat = np.stack([frame.left.aux["material"], frame.right.aux["material"]])
        configured = np.isin(mat, ids)
        changed = np.abs(hdr1 - hdr0).max(-1) > 0
        assert configured.any() and changed.any()
        assert not (changed & ~configured).any(), f"{cfg}: pixels of other materials changed"
        assert changed[configured].mean() > 0.3


# ------------------------------------------------------------------------------ analytic mirrors

H, CELLS = 10.0, 4


def cell_cube():
    """An inward box of half-size H, each face split into CELLS x CELLS emissive cells of unique colour."""
    parts, mats = [], []
    step = 2 * H / CELLS
    for axis in range(3):
        b, c = [a for a in range(3) if a != axis]
        for sign in (-1, 1):
            for i in range(CELLS):
                for j in range(CELLS):
                    idx = len(mats)
                    center = np.zeros(3)
                    center[axis] = sign * H
                    center[b] = -H + (i + 0.5) * step
                    center[c] = -H + (j + 0.5) * step
                    u, v = np.zeros(3), np.zeros(3)
                    u[b], v[c] = step / 2, step / 2
                    parts.append(quad(center, u, v))
                    e = ((idx % 6 + 1) / 8, ((idx // 6) % 4 + 1) / 8, (idx // 24 + 1) / 8)
                    mats.append(Material(f"cell{idx}", base_color=(0, 0, 0, 1), emission=e, double_sided=True))
    return parts, mats


def expected_cell_colour(p, r, mats):
    """Colour of the cell the rays p + t r (t > 0) reach, and the distance to the nearest cell edge."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t_axis = (np.sign(r) * H - p) / r
    t_axis = np.where(np.isfinite(t_axis) & (t_axis > 0), t_axis, np.inf)
    axis = t_axis.argmin(-1)
    t = t_axis.min(-1)
    q = p + t[..., None] * r
    sign = np.sign(np.take_along_axis(q, axis[..., None], -1)[..., 0])
    step = 2 * H / CELLS
    colour = np.zeros(p.shape)
    margin = np.full(p.shape[:-1], np.inf)
    emission = np.array([m.emission for m in mats])
    for a in range(3):
        b, c = [x for x in range(3) if x != a]
        sel = axis == a
        ui, vj = (q[..., b] + H) / step, (q[..., c] + H) / step
        i, j = np.clip(np.floor(ui), 0, CELLS - 1).astype(int), np.clip(np.floor(vj), 0, CELLS - 1).astype(int)
        idx = (a * 2 + (sign > 0)) * CELLS * CELLS + i * CELLS + j
        colour[sel] = emission[idx[sel]]
        edge = np.minimum(np.minimum(ui - np.floor(ui), np.ceil(ui) - ui), np.minimum(vj - np.floor(vj), np.ceil(vj) - vj))
        margin[sel] = (edge * step)[sel]
    return colour, margin, t


@pytest.mark.parametrize("shape", ["plane", "sphere"])
def test_mirror_reflections_hit_where_geometry_says(gl, shape):
    parts, mats = cell_cube()
    if shape == "plane":
        mirror = quad((0, -3, 0), (9, 0, 0), (0, 0, -9))
        eye, target = (1.0, 2.0, 6.0), (0.0, -3.0, 0.0)
    else:
        s = trimesh.creation.icosphere(subdivisions=4, radius=2.0)
        mirror = (s.vertices, s.faces)
        eye, target = (1.0, 1.5, 6.5), (0.0, 0.0, 0.0)
    v, f, part = merge(*parts, mirror)
    mats = mats + [Material("mirror", base_color=(1, 1, 1, 1), metallic=1.0, roughness=0.0)]
    scene = from_arrays(v, f, triangle_material=part, materials=mats, lights=no_light())
    rig = StereoRig(Pose.look_at(eye, target), ipd=0.3, fov_y=60, size=(64, 48))
    frame, img, _ = render(gl, scene, rig, {"materials": {"mirror": "reflections"}}, DARK)
    mirror_id = len(mats) - 1
    checked = 0
    for layer, e in enumerate(rig.eyes()):
        aux = frame[e.name].aux
        on = aux["material"] == mirror_id
        p = aux["position"][on]
        d = e.ray_directions()[on]
        n = np.array([0.0, 1.0, 0.0]) if shape == "plane" else p / np.linalg.norm(p, axis=-1, keepdims=True)
        n = np.broadcast_to(n, p.shape)
        cos = -(d * n).sum(-1)
        r = d + 2 * cos[:, None] * n
        colour, margin, t = expected_cell_colour(p, r, mats)
        angle = 1e-3 if shape == "plane" else 0.03  # the sphere's interpolated normals are not exact
        keep = (margin > angle * t) & (cos > 0.2)
        got = img[layer][on]
        ok = np.abs(got - colour).max(-1) < 2e-3
        assert keep.sum() > 200
        assert ok[keep].mean() >= 0.99, f"{e.name}: {ok[keep].mean():.3%} of mirror pixels show the expected cell"
        checked += keep.sum()
    assert checked > 500


@pytest.mark.parametrize("bounces", [1, 2, 4])
def test_mirror_corridor_stops_after_n_bounces(gl, bounces):
    """A square mirror tube whose walls glow 1 (red): a pixel's value counts the surfaces its path
    visited, so it is exactly bounces + 1 wherever the path stays in the tube."""
    L = 1000.0
    walls = [quad((x, 0, -L / 2), (0, 1, 0), (0, 0, L / 2 + 1)) for x in (-1, 1)] + \
            [quad((0, y, -L / 2), (1, 0, 0), (0, 0, L / 2 + 1)) for y in (-1, 1)]
    v, f, _ = merge(*walls)
    mirror = Material("mirror", base_color=(1, 1, 1, 1), metallic=1.0, roughness=0.0, emission=(1.0, 0.0, 0.0),
                      double_sided=True)  # the walls glow on both faces, whichever way they are wound
    scene = from_arrays(v, f, materials=[mirror], lights=no_light())
    rig = StereoRig(Pose.look_at((0.1, -0.2, 0.0), (0.4, 0.3, -1.0)), ipd=0.1, fov_y=70, size=(40, 30))
    frame, img, _ = render(gl, scene, rig, everything("reflections", bounces=bounces), DARK)
    for layer, e in enumerate(rig.eyes()):
        near = (frame[e.name].depth > 0) & (frame[e.name].depth < 3.0)
        assert near.mean() > 0.5
        red = img[layer][..., 0]
        assert np.all(red[near] == bounces + 1), np.unique(red[near])
        assert red.max() <= bounces + 1  # no path goes on past its last bounce


CORRIDOR_D, CORRIDOR_H, COLS_X, ROW_Y = 6.0, 8.0, 8, 1.0


def two_mirror_corridor():
    """Mirrors at x = -1 and x = +1 (z from -D to 3, |y| < H) and, at z = -D between them, a back
    wall of emissive cells (COLS_X columns across x, rows ROW_Y high), each of its own colour."""
    D, Hc = CORRIDOR_D, CORRIDOR_H
    zc, zh = (3.0 - D) / 2, (3.0 + D) / 2
    parts = [quad((-1, 0, zc), (0, 0, zh), (0, Hc, 0)), quad((1, 0, zc), (0, Hc, 0), (0, 0, zh))]  # both face inwards
    mirror = Material("mirror", base_color=(1, 1, 1, 1), metallic=1.0, roughness=0.0)
    mats = [mirror, Material("mirror_b", base_color=(1, 1, 1, 1), metallic=1.0, roughness=0.0)]
    w, rows = 2.0 / COLS_X, int(2 * Hc / ROW_Y)
    for i in range(COLS_X):
        for j in range(rows):
            parts.append(quad((-1 + (i + 0.5) * w, -Hc + (j + 0.5) * ROW_Y, -D), (w / 2, 0, 0), (0, ROW_Y / 2, 0)))
            mats.append(Material(f"cell_{i}_{j}", base_color=(0, 0, 0, 1),
                                 emission=((i + 1) / COLS_X, (j + 1) / rows, 0.25 + 0.5 * ((i + j) % 2))))
    v, f, part = merge(*parts)
    return from_arrays(v, f, triangle_material=part, materials=mats, lights=no_light())


def corridor_by_unfolding(origin, d):
    """What each ray (origin inside the corridor, d going to -z) sees, by unfolding: between mirrors
    at x = +-1 the ray is the straight line through the mirror images of the corridor, whose walls
    are the lines x = odd integer; it reaches the back wall at the unfolded x_u after as many
    reflections as odd integers lie between x0 and x_u, at the real x = x_u folded back into
    [-1, 1] (period 4). Returns (reflections, folded x, y at the wall, distance, first mirror: 0 for
    x = -1, 1 for x = +1, -1 for none)."""
    t = (-CORRIDOR_D - origin[2]) / d[..., 2]
    xu = origin[0] + t * d[..., 0]
    reflections = np.abs(np.floor((xu + 1) / 2) - np.floor((origin[0] + 1) / 2)).astype(int)
    s = np.mod(xu + 1, 4.0)
    x = np.where(s <= 2, s - 1, 3 - s)
    first = np.where(reflections == 0, -1, np.where(d[..., 0] > 0, 1, 0))
    return reflections, x, origin[1] + t * d[..., 1], t, first


@pytest.mark.parametrize("bounces", [2, 3])
def test_two_mirror_corridor_second_bounce_lands_where_unfolding_says(gl, bounces):
    """Two parallel mirrors and a back wall of coloured cells: a pixel whose ray is reflected k <=
    `bounces` times shows the cell the unfolded straight line reaches (folded back between the
    mirrors); one reflected more often ends on a mirror and shows black (no light, no ambient,
    mirrors without emission). A later bounce sent in a wrong direction (reversed, or about the
    wrong vector) ends elsewhere: another cell, a mirror or the open front."""
    scene = two_mirror_corridor()
    rig = StereoRig(Pose.look_at((0.35, 0.2, 1.5), (-0.9, -0.1, -4.0)), ipd=0.2, fov_y=60, size=(48, 36))
    frame, img, _ = render(gl, scene, rig, {"materials": {"mirror*": {"effect": "reflections", "bounces": bounces}}},
                           DARK)
    emission = np.array([m.emission for m in scene.materials])
    rows = int(2 * CORRIDOR_H / ROW_Y)
    seen = {}
    for layer, e in enumerate(rig.eyes()):
        d = e.ray_directions()
        k, x, y, t, first = corridor_by_unfolding(e.position, d)
        col = np.clip(np.floor((x + 1) / (2.0 / COLS_X)), 0, COLS_X - 1).astype(int)
        row = np.clip(np.floor((y + CORRIDOR_H) / ROW_Y), 0, rows - 1).astype(int)
        want = emission[2 + col * rows + row]
        want[k > bounces] = 0.0  # the path ends on its last mirror: black
        # away from cell edges (and the wall's corners) by more than float error
        fx, fy = (x + 1) / (2.0 / COLS_X), (y + CORRIDOR_H) / ROW_Y
        margin = np.minimum(np.abs(fx - np.round(fx)) * 2.0 / COLS_X, np.abs(fy - np.round(fy)) * ROW_Y)
        keep = (margin > 1e-3 * t) & (np.abs(y) < CORRIDOR_H - 1)
        mat = frame[e.name].aux["material"]
        assert np.array_equal(np.where(first >= 0, first, 2)[keep], np.minimum(mat, 2)[keep])  # the raster agrees
        ok = np.abs(img[layer] - want).max(-1) < 2e-3
        for n in range(bounces + 2):
            sel = keep & (k == n)
            if sel.any():
                seen[n] = seen.get(n, 0) + int(sel.sum())
                assert ok[sel].mean() >= 0.99, f"{e.name}: {ok[sel].mean():.1%} of the pixels reflected {n} times are right"
    # every regime is there: direct, 1 .. bounces reflections, and paths cut at the last mirror
    assert all(seen.get(n, 0) >= 30 for n in range(bounces + 2)), seen


# ------------------------------------------------------------------------------ against Embree

def shadow_check(gl, scene, rig, light_pos, min_lit=200):
    """Pixels the GPU shades as occluded from a point light vs Embree's occlusion of the same rays."""
    scene.lights = [Light("point", (1, 1, 1), 20.0, position=tuple(light_pos))]
    _, raster, _ = render(gl, scene, rig, {}, DARK)
    frame, shadowed, _ = render(gl, scene, rig, {"default": "shadows"}, DARK)
    es = embree(scene.vertices, scene.indices)
    light = (np.asarray(light_pos) - scene.origin).astype(np.float32)
    agree, total = 0, 0
    for layer, e in enumerate(rig.eyes()):
        aux = frame[e.name].aux
        tri = aux["triangle"]
        emissive = np.array([max(m.emission) > 0 for m in scene.materials])[scene.triangle_material[np.where(tri == NO_HIT, 0, tri)]]
        lit = (raster[layer].sum(-1) > 1e-3) & (tri != NO_HIT) & ~emissive
        p = (aux["position"][lit] - scene.origin).astype(np.float32)
        t = scene.vertices[scene.indices[tri[lit]]]
        ng = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        ng = (ng / np.linalg.norm(ng, axis=1, keepdims=True)).astype(np.float32)
        to = light - p
        dist = np.linalg.norm(to, axis=1)
        ng *= np.where((ng * to).sum(1) >= 0, 1, -1)[:, None].astype(np.float32)
        o = offset_ray(p, ng)
        d = (to / dist[:, None]).astype(np.float32)
        occluded_embree = es.run(o, d, dists=(dist * (1 - 1e-4)).astype(np.float32), query="OCCLUDED") != -1
        occluded_gpu = shadowed[layer][lit].sum(-1) < 0.5 * raster[layer][lit].sum(-1)
        agree += int((occluded_embree == occluded_gpu).sum())
        total += int(lit.sum())
        assert occluded_gpu.any() and (~occluded_gpu).any()
    assert total >= min_lit
    return agree / total


def test_shadow_rays_match_embree_default_scene(gl):
    scene = load()
    rig = StereoRig.for_scene(scene, size=(64, 48))
    assert shadow_check(gl, scene, rig, (0.6, 2.4, -0.6)) >= 0.995


def test_shadow_rays_match_embree_sponza(gl, shared_scene):
    scene = load(shared_scene("sponza_dabrovic/sponza.obj"))
    rig = StereoRig(Pose.look_at((-10.0, 3.0, -0.5), (8.0, 5.0, 0.5)), ipd=0.064, fov_y=80, size=(64, 48))
    assert shadow_check(gl, scene, rig, (2.0, 9.0, 1.0)) >= 0.995


def random_rigs(scene, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = scene.bounds
    for _ in range(n):
        eye = lo + (hi - lo) * rng.uniform(0.2, 0.8, 3)
        target = lo + (hi - lo) * rng.uniform(0.1, 0.9, 3)
        yield StereoRig(Pose.look_at(eye, target), ipd=float(rng.uniform(0.0, 0.3)), fov_y=float(rng.uniform(40, 100)),
                        convergence=float(rng.uniform(1, 5)) if rng.uniform() < 0.5 else None, size=(80, 60),
                        near=0.01)


@pytest.mark.parametrize("which", ["default", "sponza"])
def test_primary_rays_match_embree_and_the_raster_gbuffer(gl, shared_scene, which):
    scene = load() if which == "default" else load(shared_scene("sponza_dabrovic/sponza.obj"))
    es = embree(scene.vertices, scene.indices)
    rays = RenderSettings(primary="rays")
    for rig in random_rigs(scene, 3, seed=11 if which == "default" else 12):
        traced, _, passes = render(gl, scene, rig, settings=rays)
        assert "primary_rays" in {p.name for p in passes} and "visibility" not in {p.name for p in passes}
        raster, _, _ = render(gl, scene, rig)
        for e in rig.eyes():
            tri = traced[e.name].aux["triangle"]
            o = np.broadcast_to((e.position - scene.origin).astype(np.float32), tri.shape + (3,)).reshape(-1, 3)
            d = e.ray_directions().astype(np.float32).reshape(-1, 3)
            forward = -e.rotation[:, 2]
            tmin = (rig.near / (d @ forward)).astype(np.float32)
            res = es.run(np.ascontiguousarray(o + tmin[:, None] * d), d, output=1)
            prim_ids = res["primID"].astype(np.int64)
            eprim = np.where(prim_ids >= 0, prim_ids, NO_HIT).astype(np.uint32)
            et = np.where(res["primID"] >= 0, res["tfar"] + tmin, np.inf)
            hit = tri.reshape(-1) != NO_HIT
            pos = traced[e.name].aux["position"].reshape(-1, 3)
            t = np.where(hit, np.linalg.norm(pos - e.position, axis=1), np.inf)
            same = tri.reshape(-1) == eprim
            with np.errstate(invalid="ignore"):
                tie = ~same & hit & (eprim != NO_HIT) & (np.abs(t - et) <= 1e-5 * et)
            assert (same | tie).mean() >= 0.999, f"{(same | tie).mean():.4%} agree with Embree"
            both = same & hit
            assert both.sum() > 100
            rel = np.abs(t[both] - et[both]) / et[both]
            assert rel.max() <= 1e-5, rel.max()
            # Raster vs ray-traced G-buffer: the same triangle, or an edge tie (another triangle
            # at the same distance along the pixel's ray: shared edges, coplanar neighbours).
            rtri = raster[e.name].aux["triangle"].reshape(-1)
            rpos = raster[e.name].aux["position"].reshape(-1, 3)
            rt = np.where(rtri != NO_HIT, np.linalg.norm(rpos - e.position, axis=1), np.inf)
            with np.errstate(invalid="ignore"):
                rtie = (rtri != tri.reshape(-1)) & np.isfinite(t) & (np.abs(rt - t) <= 1e-4 * t)
            agree = (rtri == tri.reshape(-1)) | rtie
            assert agree.mean() >= 0.995, f"{agree.mean():.4%} raster/traced agreement"


@pytest.mark.parametrize("gpu_refit", [False, True])
def test_refit_moves_what_rays_see(gl, gpu_refit):
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    v, f, part = merge((sphere.vertices + [0, 0, -3], sphere.faces), quad((0, 0, -5), (6, 0, 0), (0, 6, 0)))
    scene = from_arrays(v, f, triangle_material=part, materials=[Material("ball"), Material("wall")])
    rig = StereoRig(Pose(), ipd=0.1, fov_y=60, size=(32, 24))
    # The GPU refit serves bvh2 alone; the default traversal (wide primary rays) refits on the host.
    r = Renderer(scene, gl=gl, settings=RenderSettings(primary="rays", **({"traversal": "bvh2"} if gpu_refit else {})))
    before = r.render(rig, aux=("triangle",)).left.aux["triangle"]
    assert (r.accel._refit is None) and (bool(r.accel.wide) != gpu_refit)
    moved = scene.vertices.copy()
    moved[: len(sphere.vertices)] += np.float32([0.8, 0.0, 0.0])
    r.update_vertices(moved, gpu_refit=gpu_refit)
    assert (r.accel._refit is not None) == gpu_refit
    after = r.render(rig, aux=("triangle",)).left.aux["triangle"]
    r.release()
    ref = Renderer(scene, gl=gl)
    expected = ref.render(rig, aux=("triangle",)).left.aux["triangle"]
    ref.release()
    assert (before != after).mean() > 0.05
    assert (after == expected).mean() >= 0.995


# ------------------------------------------------------------------------------ wavefront buffers

def test_wave_batches_and_shadow_chunks_give_the_same_image(gl):
    """Effect passes under a tiny buffer limit (pixel list in batches, each surface's shadow rays
    in chunks) render what they render in one go, up to float summation order."""
    from rayvr.frame.passes import trace_effect
    scene = load()
    rig = StereoRig.for_scene(scene, size=(40, 30))
    cfg = {"default": "shadows", "params": {"shadows": {"area_samples": 3}},
           "materials": {"floor": {"effect": "glossy", "samples": 2, "bounces": 2},
                         "mirror*": {"effect": "reflections", "bounces": 3}}}
    _, whole, _ = render(gl, scene, rig, cfg)
    limit = 30_000
    batch, _, hit_chunk = trace_effect.wave_plan(40 * 30 * 2, 2, 3, limit)
    assert batch < 40 * 30 * 2 and hit_chunk < 3  # the limit does split both ways
    _, split, _ = render(gl, scene, rig, cfg, wave_buffer_bytes=limit)
    assert np.allclose(split, whole, rtol=2e-3, atol=1e-4), np.abs(split - whole).max()


def test_the_wave_buffer_limit_is_the_renderers_and_sizes_its_buffers(gl):
    """Renderer(wave_buffer_bytes=N) reaches the frame's sizing: its wavefront buffers stay within N
    where another renderer's hold the whole frame at once; a limit that is no size is refused."""
    scene = load()
    rig = StereoRig.for_scene(scene, size=(40, 30))
    cfg = parse_config(everything("glossy", samples=2), "test")
    limit = 30_000
    with Renderer(scene, cfg, gl=gl, wave_buffer_bytes=limit) as small, Renderer(scene, cfg, gl=gl) as whole:
        small.render(rig)
        whole.render(rig)
        for name in ("rt_wave.glossy.paths", "rt_wave.glossy.shadows"):
            assert small.resource(name).size <= limit < whole.resource(name).size, name
    with pytest.raises(ValueError, match="wave_buffer_bytes must be a positive whole number of bytes, got 0"):
        Renderer(scene, cfg, gl=gl, wave_buffer_bytes=0)


def test_wave_plan_respects_the_limit():
    from rayvr.frame.passes.trace_effect import PATH_BYTES, SLOT_BYTES, wave_plan
    for pixels, paths, slots, limit in ((4_608_000, 1, 4, 1 << 30), (4_608_000, 16, 64, 128 << 20),
                                        (100, 1, 2, 1 << 30), (10_000, 4, 1024, 200_000)):
        batch, pixel_chunk, hit_chunk = wave_plan(pixels, paths, slots, limit, hit_slots=max(1, slots // 4))
        assert 1 <= batch <= pixels and 1 <= pixel_chunk <= slots and 1 <= hit_chunk <= max(1, slots // 4)
        assert batch * paths * PATH_BYTES <= limit
        # a pixel event's slot rows hold the batch's pixels, a hit event's its paths
        assert batch * pixel_chunk * SLOT_BYTES <= limit and batch * paths * hit_chunk * SLOT_BYTES <= limit
        assert pixel_chunk == slots or (pixel_chunk + 1) * batch * SLOT_BYTES > limit  # as large as fits


# ------------------------------------------------------------------------------ robustness, convergence

def test_no_nan_for_axis_parallel_and_grazing_rays(gl):
    """Axis-aligned box, camera looking exactly down -Z (rays along axes), a plane seen edge-on,
    every traced effect on every material."""
    box = trimesh.creation.box(extents=(4, 3, 8))
    v, f, part = merge((box.vertices, box.faces), quad((0, 0, -2), (1, 0, 0), (0, 0, 1)),
                       quad((0.5, -1.4, -1), (0, 0.05, 0), (0, 0, 2)))
    mats = [Material("box", roughness=0.0, metallic=1.0), Material("edge_on", roughness=0.3), Material("sliver")]
    scene = from_arrays(v, f, triangle_material=part, materials=mats,
                        lights=[Light("directional", direction=(0, -1, 0)), Light("point", position=(0, 1, 0)),
                                Light("rect", intensity=3, position=(0, 1.45, -1), u=(0.5, 0, 0), v=(0, 0, 0.5))])
    rig = StereoRig(Pose(np.zeros(3), np.eye(3)), ipd=0.0, fov_y=90, size=(33, 33))
    for primary in ("raster", "rays"):
        for cfg in (everything("reflections", bounces=4),
                    everything("glossy", samples=3, bounces=2),
                    everything("shadows", area_samples=5)):
            frame, img, _ = render(gl, scene, rig, cfg, RenderSettings(primary=primary))
            assert np.isfinite(img).all(), (primary, cfg)
            assert img.max() > 0


def test_soft_shadow_converges_with_more_samples(gl):
    """A square occluder under a rect light: the penumbra estimate gets closer to a 1024-sample
    reference as area_samples grows."""
    v, f, part = merge(quad((0, 0, 0), (4, 0, 0), (0, 0, -4)), quad((0, 1, 0), (0.5, 0, 0), (0, 0, -0.5)))
    scene = from_arrays(v, f, triangle_material=part, materials=[Material("floor"), Material("blocker")],
                        lights=[Light("rect", intensity=4, position=(0, 2.0, 0), u=(0.6, 0, 0), v=(0, 0, 0.6))])
    rig = StereoRig(Pose.look_at((0, 4, 2), (0, 0, 0)), ipd=0.1, fov_y=50, size=(48, 36))

    def shade(n):
        frame, img, _ = render(gl, scene, rig, everything("shadows", area_samples=n), DARK)
        return img, frame.left.aux["material"]

    ref, mat = shade(1024)
    floor = np.stack([mat, mat]) == 0
    err = {n: float(np.abs(shade(n)[0] - ref)[floor].mean()) for n in (1, 4, 16, 64)}
    assert err[1] > err[4] > err[16] > err[64], err
    assert err[64] < 0.25 * err[1], err


@pytest.mark.parametrize("effect", ["shadows", "path"])
def test_rays_leave_a_lit_face_seen_from_afar_without_hitting_it(gl, effect):
    """A lone face, tilted like CornellBox-Original's tallBox front and crossing the z = 0 plane,
    under a point light, seen from 6 units away: nothing can block its light nor return any, so
    shadow rays (`shadows`) and shadow + BSDF rays (`path`, black background) must give exactly
    the unshadowed analytic point-light shading of `raster` on every pixel. The G-buffer's point
    is eye + t * dir, off the plane by rounding errors of the eye's distance; started from there,
    rays left the face by offset_ray's few ulps of |z| (< 1e-7 where |z| ~ 0.05) and hit it
    again: dark speckles (a third of the face's pixels)."""
    n = np.array([0.3, 0.0, 0.95]) / np.linalg.norm([0.3, 0.0, 0.95])
    u = np.cross([0.0, 1.0, 0.0], n) * 0.3
    v, f = quad((0.0, 0.0, 0.0), u, (0.0, 0.6, 0.0))
    if np.cross(u, (0.0, 0.6, 0.0)) @ n < 0:
        f = f[:, ::-1]
    scene = from_arrays(v, f, materials=[Material("face", base_color=(0.8, 0.8, 0.8, 1.0), roughness=0.7)],
                        lights=[Light("point", intensity=3.0, position=(0.4, 1.5, 1.2))])
    rig = StereoRig(Pose.look_at((0.3, 0.2, 6.0), (0.0, 0.0, 0.0)), ipd=0.0, fov_y=8, size=(32, 32))
    frame, ref, _ = render(gl, scene, rig, everything("raster"), DARK)
    face = frame.left.aux["material"] == 0
    assert face.mean() > 0.3 and ref[0][face].min() > 0.01
    cfg = everything(effect, area_samples=1) if effect == "shadows" else everything(effect, samples=4, bounces=2)
    _, got, _ = render(gl, scene, rig, cfg, DARK)
    ratio = got[0][face].mean(-1) / ref[0][face].mean(-1)
    assert np.abs(ratio - 1.0).max() < 2e-3, f"{(np.abs(ratio - 1) > 2e-3).sum()} of {face.sum()} pixels off"


# ------------------------------------------------------------------------------ command line

def test_cli_capture_primary_rays_and_bench_rays_quick(tmp_path):
    import json
    cfg = tmp_path / "m.toml"
    cfg.write_text('default = "shadows"\n[materials]\n"mirror*" = { effect = "reflections", bounces = 2 }\n')
    run = run_rayvr("capture", "--primary", "rays", "--materials", cfg, "--size", "32x24", "--out", tmp_path / "o",
                    "--aux", "triangle", "--timings")
    assert run.returncode == 0, run.stderr
    summary = json.loads((tmp_path / "o" / "frame_timings.json").read_text())
    assert {"bvh", "primary_rays", "classify", "rt_shadows", "rt_reflections"} <= set(summary["passes"])
    assert "visibility" not in summary["passes"]
    result = quick_bench("rays", tmp_path / "b")
    kinds = {"primary", "shadow", "reflect", "glossy_0.1", "glossy_0.3", "glossy_0.6", "diffuse", "area_shadow"}
    assert {r["rays_kind"] for r in result["rows"]} == kinds   # the room has a rect light: area shadows too
    assert all(r["build_s"] > 0 and r["sah_cost"] > 0 for r in result["rows"])
    if "agree_with_embree" in result["rows"][0]:
        assert min(r["agree_with_embree"] for r in result["rows"] if "agree_with_embree" in r) > 0.99
    # every traversal variant per kind, each returning the reference's hits
    from rayvr.bench.rays import VARIANTS
    for kind in ("primary", "reflect"):
        assert {r["variant"] for r in result["rows"] if r["rays_kind"] == kind} >= {v[0] for v in VARIANTS}
    assert all(r["agree_with_bvh2"] == 1.0 for r in result["rows"] if r["variant"] != "bvh2 rows")
    assert set(result["meta"]["best"]) == {f"default/{k}" for k in kinds}
    frame = result["meta"]["hybrid_frames"][0]
    assert {"rt_shadows", "rt_reflections", "classify"} <= set(frame["pass_ms"]) and frame["mirror_pixel_fraction"] > 0


@pytest.mark.parametrize("ballot", ["khr", "arb", "shared"])
@pytest.mark.parametrize("group", [(8, 8), (32, 16)])
def test_classify_lists_every_traced_pixel_once_in_each_aggregation_mode(gl, ballot, group):
    from rayvr.frame.effects import traced_effects
    from rayvr.frame.passes.classify import BALLOT_MODES, ClassifyPass
    ext = BALLOT_MODES[ballot][1]
    if ext and not gl.has_extension(ext):
        pytest.skip(f"no {ext}")
    scene = load()
    rig = StereoRig.for_scene(scene, size=(37, 29))  # not a multiple of any group size
    r = Renderer(scene, parse_config({"default": "shadows", "materials": {"mirror*": "reflections"}}, "t"), gl=gl)
    try:
        plan = r.plan(2, "color")
        passes = r.compiled(plan).passes
        i = [p.name for p in passes].index("classify")
        passes[i].release()
        passes[i] = ClassifyPass(ballot, group)
        passes[i].setup(gl, plan)
        assert passes[i].mode == ballot
        for _ in range(2):  # the second frame starts from the counters the first one left
            frame = r.render(rig, aux=("effect",))
            traced = [e.name for e in traced_effects()]
            effect = np.stack([frame.left.aux["effect"], frame.right.aux["effect"]])[:, ::-1]  # rows bottom-up
            args = np.frombuffer(r.resource("rt_list_args").read(), np.uint32)
            pixels = np.frombuffer(r.resource("rt_lists").read(), np.uint32).reshape(len(traced), -1)
            assert not args[4 * len(traced):].any()  # scratch left at zero
            for s, name in enumerate(traced):
                z, y, x = np.nonzero(effect == EFFECTS[name].id)
                want = np.sort(x.astype(np.uint32) | (y.astype(np.uint32) << 14) | (z.astype(np.uint32) << 28))
                n = int(args[4 * s + 3])
                assert np.array_equal(np.sort(pixels[s, :n]), want), name
                assert tuple(args[4 * s:4 * s + 3]) == ((-(-n // 64), 1, 1) if n else (0, 1, 1))
    finally:
        r.release()


def test_shadow_chunks_follow_each_events_own_rays(gl, monkeypatch):
    """path with several paths a pixel: the pixel event lights its surface with a set of light
    samples per path (area_samples x samples slots per rect light) in rows of the batch's pixels,
    a hit event with area_samples in rows of its paths. Under a limit that fits one hit slot per
    path, the bounces run the hit kernel over the hit's chunks only (they ran over all of the
    pixel event's: 4 x the work here), the pixel event's chunks are `samples` times as large as
    a hit's, and the image is the one rendered in one go. Every shadow ray is traced
    (shadow_probes 0): adaptive shadows probe each chunk's part of a light's rays on its own."""
    from rayvr.frame.passes import trace_effect
    scene = load()
    rects = sum(light.kind == "rect" for light in scene.lights)
    others = len(scene.lights) - rects
    assert rects >= 1
    rig = StereoRig.for_scene(scene, size=(24, 18))
    cfg = {"default": "path", "params": {"path": {"samples": 4, "bounces": 2, "area_samples": 2}}}
    every_ray = RenderSettings(shadow_probes=0)
    _, whole, _ = render(gl, scene, rig, cfg, every_ray)
    hits = []
    real_run = moderngl.ComputeShader.run_indirect

    limit = 24 * 18 * 2 * 4 * trace_effect.SLOT_BYTES
    with Renderer(scene, parse_config(cfg, "<t>"), gl=gl, wave_buffer_bytes=limit, settings=every_ray) as r:
        plan = r.plan(2, "color", rig.eyes()[0].camera)
        shape = trace_effect.WaveShape(EFFECTS["path"], r.sizing(rig.size, 2, plan))
        assert shape.slots == rects * 2 * 4 + others and shape.hit_slots == rects * 2 + others
        assert shape.hit_chunk == 1 and len(shape.hit_chunks) == shape.hit_slots
        assert shape.chunk == min(shape.slots, 4 * shape.hit_chunk * 24 * 18 * 2 // shape.batch)
        assert len(shape.chunks) < shape.slots
        hit_program = next(p for p in r.graph.compile(plan).passes if p.name == "rt_path").programs["hit"]

        def counting(self, *a, **k):
            if self is hit_program:
                hits.append(1)
            return real_run(self, *a, **k)
        monkeypatch.setattr(moderngl.ComputeShader, "run_indirect", counting)
        frame = r.render(rig, aux=("hdr",))
        split = np.stack([frame.left.aux["hdr"], frame.right.aux["hdr"]])
    batches = -(-24 * 18 * 2 // shape.batch)
    assert len(hits) == batches * 2 * shape.hit_slots
    assert np.allclose(split, whole, rtol=2e-3, atol=1e-4), np.abs(split - whole).max()


def test_bench_glossy_rays_sample_ggx_visible_normals():
    """bench rays' glossy rays (rayvr/bench/rays.py ggx_visible_normals) against GGX itself: seen
    head-on the visible normals are D(m) cos(m), whose tan^2 theta is alpha^2 u / (1 - u) for a
    uniform u (quantiles compared); seen obliquely every normal faces the viewer and the upper side."""
    from rayvr.bench.rays import ggx_visible_normals

    rng = np.random.default_rng(3)
    n, alpha = 200_000, 0.3
    m = ggx_visible_normals(np.tile([[0.0, 0.0, 1.0]], (n, 1)), alpha, rng.random(n), rng.random(n))
    assert np.allclose(np.linalg.norm(m, axis=1), 1.0, atol=1e-9)
    tan2 = (m[:, 0] ** 2 + m[:, 1] ** 2) / m[:, 2] ** 2
    q = np.array([0.1, 0.25, 0.5, 0.75, 0.9])
    assert np.allclose(np.quantile(tan2, q), alpha ** 2 * q / (1 - q), rtol=0.02)
    v = np.tile([[np.sin(1.2), 0.0, np.cos(1.2)]], (n, 1))
    m = ggx_visible_normals(v, 0.6, rng.random(n), rng.random(n))
    assert ((m * v).sum(1) >= -1e-9).all() and (m[:, 2] >= 0).all()
    # and leaning towards the viewer: the visible normals' mean tilts towards +x
    assert m[:, 0].mean() > 0.05


def test_bench_rays_times_the_kinds_asked_for(tmp_path):
    result = quick_bench("rays", tmp_path, "--configs", "primary,diffuse", "--layouts", "bvh2", "--no-tiles")
    assert {r["rays_kind"] for r in result["rows"]} == {"primary", "diffuse"}
    run = run_rayvr("bench", "rays", "--quick", "--configs", "glossy", "--out", tmp_path / "x")
    assert run.returncode == 2 and "--configs must be among primary, shadow" in run.stderr
