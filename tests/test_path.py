"""The `path` effect (glsl/effects/path.glsl) and the MIS it shares with `glossy` (common/mis.glsl).

* White furnace: the camera at the centre of a closed sphere whose surface emits E everywhere and
  reflects with rayvr's BRDF. Every surface point sees the same thing, so the radiance leaving at
  cos mu from the normal solves L(mu) = E + int f(mu, l) cos(l) L(mu_l) dl (a ray leaving at mu
  meets the sphere at mu again): numpy solves it on a grid with its own BRDF
  (rayvr/reference/shading.py); a pure Lambert albedo a gives the textbook E / (1 - a).
* MIS glossy: a rough metal floor under a rect light, lit by light samples + GGX rays with MIS,
  against the same floor where the lamp is no light at all (found by GGX rays alone, many samples).
* NaN-free at grazing views and with a zero-area light; deterministic per seed."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.reference.shading import brdf_cos
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays

DARK = dict(ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0))


def render(gl, scene, rig, config, seed=0, eyes="left", aux=("hdr", "material")):
    with Renderer(scene, parse_config(config, "<test>"), gl=gl, settings=RenderSettings(seed=seed, **DARK)) as r:
        return r.render(rig, eyes=eyes, aux=aux)


def sphere_kernel(f_cos, n_mu=48, n_phi=48):
    """K[o, i]: the share of the radiance leaving at mu_i that leaves again at mu_o, for a BRDF
    (x cos) f_cos(v, l) given as unit vectors about the normal +z; midpoint rule in (mu, phi)."""
    mu = (np.arange(n_mu) + 0.5) / n_mu
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    s = np.sqrt(1 - mu * mu)
    k = np.zeros((n_mu, n_mu))
    for o in range(n_mu):
        v = np.array([s[o], 0.0, mu[o]])
        l = np.stack([s[:, None] * np.cos(phi), s[:, None] * np.sin(phi), np.broadcast_to(mu[:, None], (n_mu, n_phi))], -1)
        vals = f_cos(np.broadcast_to(v, l.shape).reshape(-1, 3), l.reshape(-1, 3)).reshape(n_mu, n_phi)
        k[o] = vals.sum(1) * (1.0 / n_mu) * (2 * np.pi / n_phi)
    return mu, k


def furnace_radiance(f_cos, emission, bounces=None):
    """Radiance leaving at normal incidence (what a camera at the centre sees): (I - K)^-1 E, or
    the sum of E K^k for k <= bounces."""
    mu, k = sphere_kernel(f_cos)
    e = np.full(len(mu), emission)
    if bounces is None:
        sol = np.linalg.solve(np.eye(len(mu)) - k, e)
    else:
        sol, term = e.copy(), e.copy()
        for _ in range(bounces):
            term = k @ term
            sol += term
    return float(np.interp(1.0, mu, sol))


def rayvr_f_cos(base, metallic, roughness):
    def f(v, l):
        n = np.broadcast_to([0.0, 0.0, 1.0], v.shape)
        p = len(v)
        return brdf_cos(n, v, l, np.full((p, 3), base), np.full(p, metallic), np.full(p, roughness))[:, 0]
    return f


def test_furnace_solver_gives_the_lambert_answer():
    """The numpy side alone: a Lambert BRDF of albedo a in the sphere gives E / (1 - a)."""
    a = 0.6
    lambert = lambda v, l: a / np.pi * l[:, 2]  # noqa: E731
    assert furnace_radiance(lambert, 2.0) == pytest.approx(2.0 / (1 - a), rel=2e-3)
    assert furnace_radiance(lambert, 2.0, bounces=1) == pytest.approx(2.0 * (1 + a), rel=2e-3)


@pytest.fixture(scope="module")
def furnace():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    base, emission = 0.5, 1.0
    # double-sided: the camera is inside, behind the outward-wound faces (one-sided emission is 0 there)
    mat = Material("shell", base_color=(base, base, base, 1.0), metallic=0.0, roughness=0.8,
                   emission=(emission, emission, emission), double_sided=True)
    scene = from_arrays(sphere.vertices, sphere.faces, normals=sphere.vertex_normals, materials=[mat],
                        lights=[Light("point", intensity=0.0)])
    rig = StereoRig(Pose.look_at((0.0, 0.0, 0.0), (0.3, 0.2, -1.0)), ipd=0.0, fov_y=60, size=(32, 24), near=0.01)
    return scene, rig, rayvr_f_cos(base, 0.0, 0.8), emission


@pytest.mark.parametrize("bounces", [1, 64])
def test_white_furnace_converges_to_the_analytic_radiance(gl, furnace, bounces):
    """64 bounces with Russian roulette: the whole series E / (1 - albedo) (here the numpy solve
    of rayvr's BRDF, albedo ~0.5); 1 bounce without roulette: E + K E exactly (the bounce limit
    counts what it says)."""
    scene, rig, f_cos, emission = furnace
    cfg = {"default": "path", "params": {"path": {"samples": 16, "bounces": bounces,
                                                  "rr_start": 3 if bounces > 1 else 64}}}
    got = render(gl, scene, rig, cfg).left.aux["hdr"][..., 0].astype(np.float64)
    assert np.isfinite(got).all()
    expected = furnace_radiance(f_cos, emission, bounces=None if bounces > 1 else 1)
    assert 1.5 < expected < 2.1  # what the setup is about: half of the light comes back, again and again
    sigma = got.std() / np.sqrt(got.size)  # pixels are independent samples (seeded per surface cell)
    assert abs(got.mean() - expected) < 5 * sigma + 0.01 * expected, (got.mean(), expected, sigma)


def lamp_scene(as_light: bool, roughness=0.3, zero_area=False, metallic=1.0):
    """A rough white metal floor (y = 0) under a square emitter facing down; the emitter is a
    rect light (light samples + GGX rays, MIS) or only glowing geometry (GGX rays alone)."""
    floor = quad((0, 0, 0), (4, 0, 0), (0, 0, -4))
    lamp = quad((0.0, 1.0, -1.0), (0.4, 0, 0), (0, 0, 0.4))  # faces -y: cross(u, v) = -y
    v, f, part = merge(floor, lamp)
    mats = [Material("floor", base_color=(1, 1, 1, 1), metallic=metallic, roughness=roughness),
            Material("lamp", base_color=(0, 0, 0, 1), emission=(4.0, 4.0, 4.0))]
    lights = None if as_light else [Light("point", intensity=0.0)]
    if zero_area:
        lights = [Light("rect", intensity=5.0, position=(0.0, 1.0, -1.0), u=(0.0, 0.0, 0.0), v=(0.4, 0.0, 0.0))]
    scene = from_arrays(v, f, triangle_material=part, materials=mats, lights=lights)
    assert (scene.lights[0].kind == "rect") == (as_light or zero_area)
    return scene


def test_mis_glossy_converges_to_bsdf_only_sampling(gl):
    """The lamp's reflection with MIS (16 GGX rays, 16 light samples) matches 1024 GGX rays and no
    light sampling, per pixel within their noise; counting the highlight twice (no MIS) would make
    it about twice as bright."""
    rig = StereoRig(Pose.look_at((0.0, 1.2, 1.6), (0.0, 0.0, -1.2)), ipd=0.0, fov_y=50, size=(40, 30))
    ref = render(gl, lamp_scene(False), rig, {"default": "raster", "materials": {"floor": {
        "effect": "glossy", "samples": 1024}}}, seed=11).left.aux
    mis = render(gl, lamp_scene(True), rig, {"default": "raster", "materials": {"floor": {
        "effect": "glossy", "samples": 16, "area_samples": 16}}}, seed=3).left.aux
    floor = (ref["material"] == 0) & (mis["material"] == 0)
    a, b = mis["hdr"][floor].mean(-1).astype(np.float64), ref["hdr"][floor].mean(-1).astype(np.float64)
    assert np.isfinite(a).all() and b.mean() > 0.05, b.mean()  # the lamp shows on the floor
    lit = b > 0.05 * b.max()
    assert lit.sum() > 50
    assert a[lit].mean() == pytest.approx(b[lit].mean(), rel=0.04)
    assert np.abs(a - b).mean() < 0.08 * b[lit].mean()
    # the light samples alone (no GGX rays reach a light that is not geometry) see the same lamp
    light_only = render(gl, lamp_scene(True), rig, {"default": "raster", "materials": {"floor": {
        "effect": "shadows", "area_samples": 256}}}).left.aux
    c = light_only["hdr"][floor].mean(-1).astype(np.float64)
    assert c[lit].mean() == pytest.approx(b[lit].mean(), rel=0.1)


@pytest.mark.parametrize("metallic,roughness", [(1.0, 0.3), (0.0, 0.8)])
def test_path_direct_light_is_the_light_sampled_direct_light(gl, metallic, roughness):
    """Floor and lamp only (the lamp reflects nothing, the rest is black void): all the light a
    path brings to the floor is the lamp's direct light, found by light samples and BSDF rays and
    weighed by MIS. It must equal `shadows` with many light samples (no BSDF rays, no MIS) within
    the noise, for a glossy metal and a rough dielectric floor."""
    rig = StereoRig(Pose.look_at((0.0, 1.2, 1.6), (0.0, 0.0, -1.2)), ipd=0.0, fov_y=50, size=(40, 30))
    scene = lamp_scene(True, roughness, metallic=metallic)
    ref = render(gl, scene, rig, {"default": "raster", "materials": {"floor": {
        "effect": "shadows", "area_samples": 256}}}).left.aux
    got = render(gl, scene, rig, {"default": "raster", "materials": {"floor": {
        "effect": "path", "samples": 16, "bounces": 2}}}, seed=9).left.aux
    floor = (ref["material"] == 0) & (got["material"] == 0)
    a, b = got["hdr"][floor].mean(-1).astype(np.float64), ref["hdr"][floor].mean(-1).astype(np.float64)
    assert np.isfinite(a).all() and b.mean() > 0.05
    assert a.mean() == pytest.approx(b.mean(), rel=0.03)
    assert np.abs(a - b).mean() < 0.25 * b.mean()  # per pixel: 16 paths of a glossy highlight are noisy


def test_path_at_grazing_views_and_zero_area_lights_is_finite(gl):
    """A camera skimming the floor (grazing primary and secondary rays), a mirror-sharp and a rough
    floor, and a rect light of zero area: no NaN or inf, and the zero-area light adds nothing."""
    rig = StereoRig(Pose.look_at((0.0, 1e-3, 2.0), (0.0, 0.0, -4.0)), ipd=0.064, fov_y=60, size=(32, 24), near=1e-4)
    for rough in (0.0, 0.5):
        for effect in ("path", "glossy"):
            cfg = {"default": effect, "params": {effect: {"samples": 4}}}
            for zero in (False, True):
                hdr = render(gl, lamp_scene(False, rough, zero_area=zero), rig, cfg, eyes="both")
                for e in ("left", "right"):
                    assert np.isfinite(hdr[e].aux["hdr"]).all(), (rough, effect, zero, e)
    top = StereoRig(Pose.look_at((0.0, 0.5, 1.0), (0.0, 0.0, -1.0)), ipd=0.0, fov_y=50, size=(24, 18))
    cfg = {"default": "path", "params": {"path": {"samples": 2}}}
    with_zero = render(gl, lamp_scene(False, zero_area=True), top, cfg).left.aux["hdr"]
    without = render(gl, lamp_scene(False), top, cfg).left.aux["hdr"]
    assert np.array_equal(with_zero, without)


def test_path_is_deterministic_per_seed(gl):
    rig = StereoRig(Pose.look_at((0.0, 1.2, 1.6), (0.0, 0.0, -1.2)), ipd=0.064, fov_y=50, size=(24, 18))
    cfg = {"default": "path", "params": {"path": {"samples": 2, "area_samples": 2}}}
    scene = lamp_scene(True, roughness=0.6)
    a = render(gl, scene, rig, cfg, seed=5, eyes="both")
    b = render(gl, scene, rig, cfg, seed=5, eyes="both")
    c = render(gl, scene, rig, cfg, seed=6, eyes="both")
    for e in ("left", "right"):
        assert np.array_equal(a[e].aux["hdr"], b[e].aux["hdr"])
        assert not np.array_equal(a[e].aux["hdr"], c[e].aux["hdr"])


def test_a_profiled_frame_times_every_bounce_of_a_kernel(gl):
    """Each bounce runs the `closest` kernel again: every run gets its own timer query and read_ms
    sums them (one shared query kept only the last run: rt_glossy's last, empty batch read 0.01 ms)."""
    rig = StereoRig(Pose.look_at((0.0, 1.2, 1.6), (0.0, 0.0, -1.2)), ipd=0.064, fov_y=50, size=(24, 18))
    cfg = {"default": "path", "params": {"path": {"bounces": 3}}}
    with Renderer(lamp_scene(True), parse_config(cfg, "<test>"), gl=gl, settings=RenderSettings(**DARK)) as r:
        fc = r.record(rig, "both", "color", profile=True)
        names = [n for n in fc.stage_names if n.split("#")[0] == "rt_path.closest"]
        ms = r.read_ms(fc)
        each = r.graph.kernel_timer.read_ms(names, fc.timer_slot)
    assert len(names) == 3 and len(set(names)) == 3
    assert ms["rt_path.closest"] == pytest.approx(sum(each.values()))
    assert ms["rt_path.closest"] > max(each.values())
