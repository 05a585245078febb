"""Which side emissive geometry lights, checked analytically (rayvr/scene/loader.py Material.double_sided).

The rule: emission leaves a triangle's front face only (the side its winding's normal points to),
unless the material is double-sided (glTF `doubleSided`; OBJ emitters are one-sided). It holds for
the emission the camera sees, for what path/glossy rays find, and for an emissive rectangle's
rect light (one-sided, or two-sided for a double-sided material).

The reference: a floor (y = 0) under a unit square emitter of radiance L at height 1. The light
a floor point reflects towards the eye is the integral over the emitter of f(v, l) cos_floor
cos_lamp / r^2 L dA: numpy quadrature with rayvr's BRDF written in numpy (numpy_shading.brdf_cos),
the quadrature itself held to the closed form of a parallel rectangle's irradiance (its form
factor to a point) for a Lambertian floor. The emitter faces the floor (lit), faces away (no
direct light from it at all) or faces away but is double-sided (lit as if it faced the floor)."""
from __future__ import annotations

import base64
import json

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.scene import loader as scene_mod
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.reference.shading import brdf_cos, shade_eye
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays

L = 3.0                                  # the lamp's radiance
LAMP_C, LAMP_HALF = np.array([0.0, 1.0, -0.6]), 0.5   # unit square, 1 above the floor
FLOOR = dict(base=0.8, metallic=0.0, roughness=0.6)
DARK = dict(ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0))
RIG = StereoRig(Pose.look_at((0.0, 0.55, 1.6), (0.0, 0.25, -1.0)), ipd=0.0, fov_y=60, size=(40, 30))


# ------------------------------------------------------------------ the reference (numpy only)

def corner_form_factor(x, z, h):
    """Form factor from a floor point to the parallel rectangle [0, x] x [0, z] at height h above
    it (one corner straight above the point), signed by the rectangle's quadrant."""
    a, b = np.abs(x) / h, np.abs(z) / h
    f = (a / np.sqrt(1 + a * a) * np.arctan(b / np.sqrt(1 + a * a))
         + b / np.sqrt(1 + b * b) * np.arctan(a / np.sqrt(1 + b * b))) / (2 * np.pi)
    return np.sign(x) * np.sign(z) * f


def parallel_rect_irradiance(p, centre, half, radiance):
    """Irradiance at floor points p (N, 3) from a square of radiance `radiance` facing down, by
    superposing the four corner rectangles: E = pi L F."""
    h = centre[1] - p[:, 1]
    x0, x1 = centre[0] - half - p[:, 0], centre[0] + half - p[:, 0]
    z0, z1 = centre[2] - half - p[:, 2], centre[2] + half - p[:, 2]
    f = (corner_form_factor(x1, z1, h) - corner_form_factor(x0, z1, h)
         - corner_form_factor(x1, z0, h) + corner_form_factor(x0, z0, h))
    return np.pi * radiance * f


def lamp_integral(p, v, f_cos, facing_down=True, double_sided=False, n=48):
    """sum over an n x n midpoint grid of the lamp of f_cos(l) L cos_lamp / r^2 dA at floor points
    p (N, 3) seen along unit v (N, 3) (towards the eye); the lamp lights only the side it faces
    unless double-sided."""
    s = (np.arange(n) + 0.5) / n * 2 - 1
    q = (LAMP_C + LAMP_HALF * np.stack(np.meshgrid(s, s, indexing="ij"), -1).reshape(-1, 2) @ [[1, 0, 0], [0, 0, 1]])
    lamp_n = np.array([0.0, -1.0 if facing_down else 1.0, 0.0])
    d_a = (2 * LAMP_HALF / n) ** 2
    out = np.zeros(len(p))
    for k in range(len(q)):
        d = q[k] - p
        r2 = (d * d).sum(-1)
        l = d / np.sqrt(r2)[:, None]
        cos_lamp = -l @ lamp_n
        if double_sided:
            cos_lamp = np.abs(cos_lamp)
        out += f_cos(v, l) * L * np.maximum(cos_lamp, 0.0) / r2 * d_a
    return out


def floor_f_cos(v, l):
    m = len(v)
    n = np.broadcast_to([0.0, 1.0, 0.0], v.shape)
    return brdf_cos(n, v, l, np.full((m, 3), FLOOR["base"]), np.full(m, FLOOR["metallic"]),
                    np.full(m, FLOOR["roughness"]))[:, 0]


def test_the_quadrature_is_the_closed_form_of_a_parallel_rectangle():
    """A Lambertian floor of albedo 1 (f cos = cos / pi) reflects E / pi: the quadrature against
    the form factor under the lamp's centre, under a corner and outside it; nothing from a lamp
    that faces away, and the same from a double-sided one."""
    p = np.array([[0.0, 0.0, -0.6], [0.5, 0.0, -1.1], [1.7, 0.0, 0.4], [-0.2, 0.0, -0.3]])
    v = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    lambert = lambda v, l: np.maximum(l[:, 1], 0.0) / np.pi  # noqa: E731
    closed = parallel_rect_irradiance(p, LAMP_C, LAMP_HALF, L) / np.pi
    # a unit square one above: form factor 0.2394 under its centre (the tabulated value)
    assert closed[0] / L == pytest.approx(0.2394, abs=2e-4)
    np.testing.assert_allclose(lamp_integral(p, v, lambert), closed, rtol=2e-3)
    assert np.all(lamp_integral(p, v, lambert, facing_down=False) == 0.0)
    np.testing.assert_allclose(lamp_integral(p, v, lambert, facing_down=False, double_sided=True), closed, rtol=2e-3)


# ------------------------------------------------------------------ rayvr against it

def lamp_scene(facing_down: bool, double_sided: bool, as_light: bool = True):
    floor = quad((0, 0, 0), (3, 0, 0), (0, 0, -3))  # faces +y
    u, w = (LAMP_HALF, 0, 0), (0, 0, LAMP_HALF)
    lamp = quad(LAMP_C, u, w) if facing_down else quad(LAMP_C, w, u)  # front face along cross(u, v)
    v, f, part = merge(floor, lamp)
    mats = [Material("floor", base_color=(FLOOR["base"],) * 3 + (1.0,), metallic=FLOOR["metallic"],
                     roughness=FLOOR["roughness"]),
            Material("lamp", base_color=(0, 0, 0, 1), emission=(L, L, L), double_sided=double_sided)]
    scene = from_arrays(v, f, triangle_material=part, materials=mats, emissive_lights=as_light,
                        ambient_lights=False)
    assert [x.kind for x in scene.lights] == (["rect"] if as_light else [])
    return scene


def render(gl, scene, config, seed=0):
    with Renderer(scene, parse_config(config, "<test>"), gl=gl, settings=RenderSettings(seed=seed, **DARK)) as r:
        return r.render(RIG, eyes="left", aux=("hdr", "material", "position")).left.aux


def expected_floor(scene, aux, facing_down, double_sided):
    floor = aux["material"] == scene.material_names().index("floor")
    p = aux["position"][floor].astype(np.float64)
    assert np.abs(p[:, 1]).max() < 1e-4  # world positions on the floor
    v = RIG.eyes()[0].position - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return floor, lamp_integral(p, v, floor_f_cos, facing_down, double_sided)


SIDES = [(True, False), (False, False), (False, True), (True, True)]
SIDE_IDS = ["facing", "away", "away-double-sided", "facing-double-sided"]
# effect config, tolerance on the floor's mean, on the mean per-pixel difference (measured: at most
# 0.4 % and 3.2 %)
EFFECTS = {
    "raster": ({"default": "raster"}, 0.01, 0.02),
    "shadows": ({"default": "shadows", "params": {"shadows": {"area_samples": 64}}}, 0.01, 0.04),
    "glossy": ({"default": "glossy", "params": {"glossy": {"samples": 16, "area_samples": 16}}}, 0.01, 0.08),
    "path": ({"default": "path", "params": {"path": {"samples": 16, "bounces": 2}}}, 0.02, 0.10),
}


@pytest.mark.parametrize("effect", list(EFFECTS))
@pytest.mark.parametrize("facing_down,double_sided", SIDES, ids=SIDE_IDS)
def test_a_rect_light_lights_the_floor_as_the_closed_form_on_the_sides_it_emits(gl, effect, facing_down,
                                                                                double_sided):
    config, mean_tol, pixel_tol = EFFECTS[effect]
    scene = lamp_scene(facing_down, double_sided)
    aux = render(gl, scene, config, seed=3)
    floor, want = expected_floor(scene, aux, facing_down, double_sided)
    got = aux["hdr"][floor].mean(-1).astype(np.float64)
    assert floor.sum() > 300 and np.isfinite(got).all()
    lamp = aux["material"] == 1
    assert lamp.sum() > 20  # the camera (below the lamp) sees its underside
    seen = aux["hdr"][lamp].astype(np.float64)
    if facing_down or double_sided:
        assert want.mean() > 0.1
        assert got.mean() == pytest.approx(want.mean(), rel=mean_tol)
        assert np.abs(got - want).mean() < pixel_tol * want.mean()
        # the emitter shows its radiance (plus, where rays are traced, a glint of the lit floor)
        assert seen.min() >= L * (1 - 1e-3) and seen.max() <= 1.01 * L, (seen.min(), seen.max())
    else:  # its back: no light on the floor from it, and it shows black
        assert np.all(want == 0.0)
        assert np.abs(got).max() == 0.0, f"{effect}: the back of a one-sided lamp lit the floor: {got.max():.4f}"
        assert np.abs(seen).max() == 0.0, f"{effect}: the back of a one-sided lamp glows: {seen.max():.4f}"


@pytest.mark.parametrize("facing_down,double_sided", SIDES[:3], ids=SIDE_IDS[:3])
def test_glowing_geometry_that_is_no_light_lights_paths_only_from_its_emitting_side(gl, facing_down, double_sided):
    """The emitter is no rect light: `path` finds it by BSDF rays alone, which must see its
    emission on the sides it emits only (two-sided emission lit the floor from the back)."""
    scene = lamp_scene(facing_down, double_sided, as_light=False)
    aux = render(gl, scene, {"default": "path", "params": {"path": {"samples": 64, "bounces": 1}}}, seed=5)
    floor, want = expected_floor(scene, aux, facing_down, double_sided)
    got = aux["hdr"][floor].mean(-1).astype(np.float64)
    if facing_down or double_sided:
        assert got.mean() == pytest.approx(want.mean(), rel=0.05)
    else:
        assert got.max() == 0.0, f"BSDF rays found emission on the back of a one-sided emitter: {got.mean():.4f}"


@pytest.mark.parametrize("facing_down,double_sided", SIDES[:3], ids=SIDE_IDS[:3])
def test_numpy_reference_follows_the_same_rule(facing_down, double_sided):
    """numpy_shading.shade_eye (rayvr's independent direct-light reference): the lamp's back is
    black and lights nothing unless double-sided; its floor is the closed form's quadrature."""
    scene = lamp_scene(facing_down, double_sided)
    eye = RIG.eyes()[0]
    ref = shade_eye(scene, eye, "shadows", ambient=(0, 0, 0), background=(0, 0, 0), rect_samples=64)
    floor, lamp = ref["material"] == 0, ref["material"] == 1
    dirs = eye.ray_directions()[floor]
    p = eye.position + dirs * (-eye.position[1] / dirs[:, 1])[:, None]  # where the rays meet y = 0
    want = lamp_integral(p, -dirs, floor_f_cos, facing_down, double_sided)
    got = ref["hdr"][floor].mean(-1)
    if facing_down or double_sided:
        assert got.mean() == pytest.approx(want.mean(), rel=0.02)
        np.testing.assert_allclose(ref["hdr"][lamp], L)
    else:
        assert got.max() < 1e-6 and ref["hdr"][lamp].max() < 1e-6  # (light grazing the lamp's own plane)


# ------------------------------------------------------------------ which emitters are lights

def gltf_lamp_file(path, double_sided: bool):
    """A glTF with a floor, an emissive square (doubleSided as given) facing down, and a
    KHR_lights_punctual point light under the floor (it lights nothing the camera sees: the
    floor's top faces away from it and the floor hides it)."""
    floor_v, floor_f = quad((0, 0, 0), (3, 0, 0), (0, 0, -3))
    lamp_v, lamp_f = quad(LAMP_C, (LAMP_HALF, 0, 0), (0, 0, LAMP_HALF))
    blob, views, accessors, meshes = b"", [], [], []
    for v, f in ((floor_v, floor_f), (lamp_v, lamp_f)):
        for data, kind, ctype, target in ((np.asarray(v, "<f4"), "VEC3", 5126, 34962),
                                          (np.asarray(f, "<u4").ravel(), "SCALAR", 5125, 34963)):
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes, "target": target})
            acc = {"bufferView": len(views) - 1, "componentType": ctype, "count": len(data), "type": kind}
            if kind == "VEC3":
                acc.update(min=data.min(0).tolist(), max=data.max(0).tolist())
            accessors.append(acc)
            blob += data.tobytes()
        meshes.append({"primitives": [{"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1,
                                       "material": len(meshes)}]})
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0, "name": "floor"}, {"mesh": 1, "name": "lamp"},
                  {"translation": [0.0, -1.0, -0.5], "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        "meshes": meshes,
        "materials": [{"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0],
                                                                 "metallicFactor": 0.0, "roughnessFactor": 0.6}},
                      {"name": "lamp", "emissiveFactor": [1.0, 1.0, 1.0], "doubleSided": double_sided,
                       "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0},
                       "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": L}}}],
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(blob).decode()}],
        "bufferViews": views, "accessors": accessors,
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5.0}]}},
    }
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("double_sided", [False, True])
def test_a_gltf_with_punctual_lights_still_makes_its_emissive_square_an_area_light(tmp_path, double_sided):
    scene = scene_mod.load(gltf_lamp_file(tmp_path / "lamp.gltf", double_sided))
    assert sorted(x.kind for x in scene.lights) == ["point", "rect"]
    rect = next(x for x in scene.lights if x.kind == "rect")
    assert rect.intensity == pytest.approx(L)
    assert np.cross(rect.u, rect.v)[1] < 0  # lights the floor, the side the triangles face
    lamp = scene.materials[scene.material_names().index("lamp")]
    assert lamp.double_sided is double_sided and rect.two_sided is double_sided


def test_the_gltf_area_light_lights_the_floor_as_the_closed_form(gl, tmp_path):
    """The file's point light (under the floor) lights nothing seen: what `shadows` shows on the
    floor is the emissive square's light, at the closed form (it was missing before)."""
    scene = scene_mod.load(gltf_lamp_file(tmp_path / "lamp.gltf", False))
    aux = render(gl, scene, EFFECTS["shadows"][0])
    floor, want = expected_floor(scene, aux, True, False)
    got = aux["hdr"][floor].mean(-1).astype(np.float64)
    assert got.mean() == pytest.approx(want.mean(), rel=0.02)


def test_an_emissive_square_that_is_already_a_light_is_not_added_twice():
    """A caller whose lights already hold the lamp's rectangle (corners in another order, edges
    the other way round) keeps one light; a different rectangle is added."""
    v, f, part = merge(quad((0, 0, 0), (3, 0, 0), (0, 0, -3)), quad(LAMP_C, (LAMP_HALF, 0, 0), (0, 0, LAMP_HALF)))
    mats = [Material("floor"), Material("lamp", emission=(L, L, L))]
    same = Light("rect", intensity=L, position=tuple(LAMP_C), u=(0, 0, -LAMP_HALF), v=(-LAMP_HALF, 0, 0))
    other = Light("rect", intensity=L, position=(0.0, 2.0, 0.0), u=(0.1, 0, 0), v=(0, 0, 0.1))
    kept = from_arrays(v, f, triangle_material=part, materials=mats, lights=[same], emissive_lights=True).lights
    assert kept == [same]
    added = from_arrays(v, f, triangle_material=part, materials=mats, lights=[other], emissive_lights=True).lights
    assert [x.source for x in added] == ["default", "emissive material lamp"]
    # callers that give their lights give them all (tests' glowing geometry that is no light)
    assert from_arrays(v, f, triangle_material=part, materials=mats, lights=[other]).lights == [other]


def test_obj_emitters_are_one_sided(tmp_path):
    (tmp_path / "lamp.mtl").write_text("newmtl lamp\nKd 0 0 0\nKe 2 2 2\nnewmtl floor\nKd 0.8 0.8 0.8\n")
    (tmp_path / "lamp.obj").write_text(
        "mtllib lamp.mtl\nv -3 0 3\nv 3 0 3\nv 3 0 -3\nv -3 0 -3\n"
        "v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\n"
        "usemtl floor\nf 1 2 3\nf 1 3 4\nusemtl lamp\nf 5 6 7\nf 5 7 8\n")
    scene = scene_mod.load(tmp_path / "lamp.obj")
    (rect,) = scene.lights
    assert not rect.two_sided and not scene.materials[scene.material_names().index("lamp")].double_sided
    assert np.cross(rect.u, rect.v)[1] < 0  # 5 6 7 8 winds clockwise seen from above: faces down


# ------------------------------------------------------------------ the Mitsuba converter

@pytest.fixture(scope="module")
def mitsuba_variant():
    pytest.importorskip("mitsuba")
    from rayvr.bench import mitsuba_ref

    return mitsuba_ref.set_variant()


@pytest.mark.parametrize("as_light", [True, False], ids=["rect-light", "emissive-mesh"])
@pytest.mark.parametrize("facing_down,double_sided", SIDES[:3], ids=SIDE_IDS[:3])
def test_the_mitsuba_scene_emits_on_the_same_sides(mitsuba_variant, facing_down, double_sided, as_light):
    """Mitsuba's `area` emitters are one-sided: the converter's copies must light the floor and
    show the lamp exactly where rayvr does (floor pixels well inside it: Mitsuba's pixel is a box
    over the pixel, the quadrature is at its centre)."""
    import mitsuba as mi

    from rayvr.bench import mitsuba_ref as M

    scene = lamp_scene(facing_down, double_sided, as_light)
    eye = RIG.eyes()[0]
    img = M.render(mi.load_dict(M.scene_dict(scene, eye, spp=64)), M.integrator("direct"), 64, seed=1)
    dirs = eye.ray_directions()
    t = -eye.position[1] / dirs[..., 1]
    p = eye.position + dirs * t[..., None]
    inner = (t > 0) & (np.abs(p[..., 0]) < 2.5) & (p[..., 2] > -2.5) & (p[..., 2] < 2.5)
    t_lamp = (LAMP_C[1] - eye.position[1]) / dirs[..., 1]
    q = eye.position + dirs * t_lamp[..., None] - LAMP_C
    on_lamp = (t_lamp > 0) & (np.maximum(np.abs(q[..., 0]), np.abs(q[..., 2])) < LAMP_HALF)
    lamp = on_lamp & (np.maximum(np.abs(q[..., 0]), np.abs(q[..., 2])) < 0.8 * LAMP_HALF)  # whole pixels
    inner &= ~on_lamp
    assert lamp.sum() > 10 and inner.sum() > 300
    got = img[inner].mean(-1)
    if facing_down or double_sided:
        want = lamp_integral(p[inner], -dirs[inner], floor_f_cos, facing_down, double_sided)
        assert got.mean() == pytest.approx(want.mean(), rel=0.03)  # the converted BSDF is within 1.4 %
        assert img[lamp].mean() == pytest.approx(L, rel=0.01)
    else:
        assert got.max() == 0.0 and img[lamp].max() == 0.0


# ------------------------------------------------------------------ two sides are two lights

def covered_lamp_scene(facing_down: bool, double_sided: bool):
    """lamp_scene under a white ceiling (y = 2, facing down): light the lamp sends up reaches the
    floor off the ceiling."""
    floor = quad((0, 0, 0), (3, 0, 0), (0, 0, -3))
    ceiling = quad((0, 2, 0), (3, 0, 0), (0, 0, 3))  # faces -y
    u, w = (LAMP_HALF, 0, 0), (0, 0, LAMP_HALF)
    v, f, part = merge(floor, ceiling, quad(LAMP_C, u, w) if facing_down else quad(LAMP_C, w, u))
    white = dict(base_color=(0.8, 0.8, 0.8, 1.0), roughness=0.9)
    mats = [Material("floor", **white), Material("ceiling", **white),
            Material("lamp", base_color=(0, 0, 0, 1), emission=(L, L, L), double_sided=double_sided)]
    return from_arrays(v, f, triangle_material=part, materials=mats, ambient_lights=False)


@pytest.mark.parametrize("effect", ["path", "photon"])
def test_a_double_sided_lamp_is_the_sum_of_its_two_one_sided_halves(gl, effect):
    """Light is linear in its sources: a double-sided lamp lights the room as a lamp facing down
    plus one facing up, direct light and the light off the ceiling together. `path` finds the
    up-going half by light samples and BSDF rays; `photon` emits half its photons upwards."""
    config = {"path": {"default": "path", "params": {"path": {"samples": 32, "bounces": 3}}},
              "photon": {"default": "photon", "params": {"photon": {"photons": 1 << 18, "radius": 0.15,
                                                                    "bounces": 2, "area_samples": 16}}}}[effect]

    def floor_mean(facing_down, double_sided):
        scene = covered_lamp_scene(facing_down, double_sided)
        aux = render(gl, scene, config, seed=2)
        return aux["hdr"][aux["material"] == 0].mean(-1).astype(np.float64).mean()

    both, down, up = floor_mean(True, True), floor_mean(True, False), floor_mean(False, False)
    assert up > 0.1 * down  # the ceiling's share is large enough to be missed
    assert both == pytest.approx(down + up, rel=0.02), (both, down, up)


def test_a_one_sided_emitter_facing_away_from_all_geometry_is_warned_about(caplog):
    """A lamp wound the wrong way lights nothing: a warning names it rather than a silent black
    room; a lamp facing the floor, or a double-sided one, is not warned about."""
    with caplog.at_level("WARNING", logger="rayvr.scene.loader"):
        lamp_scene(True, False)
        lamp_scene(False, True)
        assert not caplog.records
        lamp_scene(False, False)
    (record,) = caplog.records
    assert "'lamp' faces away from all other geometry" in record.getMessage()
