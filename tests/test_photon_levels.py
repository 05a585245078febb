"""The `photon` effect at absolute light levels, over several bounces and through a rough metal.

* Furnace: a point light at the centre of a closed grey sphere (albedo a, inside faces seen).
  All light stays in the sphere, so the photons stored after k diffuse bounces carry the power
  Phi a^k in all (Russian roulette keeps the expectation), and on a sphere the irradiance after
  each bounce is uniform (the form factor between two points of a sphere is dA / (4 pi R^2)):
  after the direct light (shadow rays), the photon map must give a / pi * Phi / A * (a + a^2 +
  ... + a^B) at every pixel, B the stored bounces. A point light has no side, so the test does
  not depend on the emission sidedness rule.
* Glossy caustic: a rough white metal wall under a directional light throws its reflection on a
  dark floor; numpy integrates rayvr's BRDF (rayvr/reference/shading.py) over the wall for the
  irradiance at each floor point, and the photons stored on the floor, and the estimate at each
  floor pixel, must match it (the GGX-sampled photon carries F G2 / G1, the BRDF's exact weight).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.accel import photon_map as pm
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.reference.shading import brdf_cos
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays

DARK = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0))

# --- furnace -------------------------------------------------------------------------------------
SHELL_ALBEDO = 0.6
INTENSITY = 2.0  # the point light's intensity: power 4 pi I
FURNACE_BOUNCES = 3
FURNACE_PATHS = 1 << 15
FURNACE_RADIUS = 0.3  # on a sphere of radius 1: the cap within chord r has area pi r^2 exactly


def render_twice(gl, scene, config, rig, seed=0):
    """(`photon` frame, `shadows` frame of the same scene and seed, the photon records)."""
    photon = parse_config(config, "<test>")
    direct = parse_config({"default": "shadows"}, "<test>")
    with Renderer(scene, photon, gl=gl, settings=replace(DARK, seed=seed)) as r:
        frame = r.render(rig, eyes="left", aux=("hdr", "position", "material"))
        records = pm.unpack_photons(r.resource("photons").read())
        r.set_materials(direct)
        shadows = r.render(rig, eyes="left", aux=("hdr",))
    return frame.left, shadows.left, records


@pytest.fixture(scope="module")
def furnace(gl):
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    a = SHELL_ALBEDO
    scene = from_arrays(sphere.vertices, sphere.faces,
                        materials=[Material("shell", base_color=(a, a, a, 1.0), metallic=0.0, roughness=1.0)],
                        lights=[Light("point", position=(0.0, 0.0, 0.0), intensity=INTENSITY)])
    config = {"default": "photon", "params": {"photon": {"photons": FURNACE_PATHS, "radius": FURNACE_RADIUS,
                                                         "bounces": FURNACE_BOUNCES, "area_samples": 1}}}
    rig = StereoRig(Pose.look_at((0.0, 0.0, 0.0), (0.3, 0.2, -1.0)), ipd=0.0, fov_y=60, size=(32, 24), near=0.01)
    frame, shadows, records = render_twice(gl, scene, config, rig)
    return scene, float(sphere.area), frame, shadows, records


def bounce_series(a: float, bounces: int) -> float:
    """a + a^2 + ... + a^bounces: the share of the power that arrives after 1..bounces bounces."""
    return sum(a ** k for k in range(1, bounces + 1))


def test_furnace_photons_carry_the_power_of_every_bounce(furnace):
    """The stored photons' power sums to Phi (a + a^2 + a^3): the light's power, divided among the
    paths, times what each diffuse bounce keeps (the closed sphere loses nothing)."""
    scene, _, _, _, ph = furnace
    stored = ph["extra"] != 0
    total = ph["power"][stored].astype(np.float64).sum(0)
    phi = 4 * np.pi * INTENSITY
    expected = phi * bounce_series(SHELL_ALBEDO, FURNACE_BOUNCES)
    # each path stores 0..3 photons of power phi / paths: the total's relative spread is
    # std(stores) / (mean(stores) sqrt(paths)) ~ 0.6 %
    assert total == pytest.approx([expected] * 3, rel=0.025), (total, expected)
    # and every one of them lies on the shell, after at least one bounce (none at the first hit)
    r = np.linalg.norm(ph["position"][stored].astype(np.float64) + scene.origin, axis=1)
    assert r.min() > 0.99 and r.max() < 1.0 + 1e-4
    assert stored.sum() == pytest.approx(FURNACE_PATHS * bounce_series(SHELL_ALBEDO, FURNACE_BOUNCES), rel=0.03)


def test_every_light_of_several_emits_its_share_of_the_photons(gl):
    """Two coloured point lights in the furnace, one red of power Phi_r, one green three times as
    strong: the stored photons carry Phi_r (a + a^2 + a^3) in red and 3 Phi_r (...) in green, so
    each light's photons are emitted and stored with its own power. (The shader once picked the
    light with a while loop whose first light, on llvmpipe, came out with no power: Sponza's sun
    was missing from its photon map beside the point light, a ratio of 0.44 to `path`'s indirect.)"""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    a = SHELL_ALBEDO
    lights = [Light("point", color=(1.0, 0.0, 0.0), position=(0.1, 0.0, 0.0), intensity=INTENSITY),
              Light("point", color=(0.0, 1.0, 0.0), position=(-0.1, 0.0, 0.0), intensity=3 * INTENSITY)]
    scene = from_arrays(sphere.vertices, sphere.faces,
                        materials=[Material("shell", base_color=(a, a, a, 1.0), metallic=0.0, roughness=1.0)],
                        lights=lights)
    config = {"default": "photon", "params": {"photon": {"photons": FURNACE_PATHS, "radius": FURNACE_RADIUS,
                                                         "bounces": FURNACE_BOUNCES}}}
    rig = StereoRig(Pose.look_at((0.0, 0.0, 0.0), (0.3, 0.2, -1.0)), ipd=0.0, fov_y=60, size=(16, 12), near=0.01)
    _, _, ph = render_twice(gl, scene, config, rig)
    total = ph["power"][ph["extra"] != 0].astype(np.float64).sum(0)
    phi = 4 * np.pi * INTENSITY * bounce_series(a, FURNACE_BOUNCES)
    # green's paths are 3/4 of them, red's 1/4: red's total spreads by ~1.3 %, green's by ~0.7 %
    assert total == pytest.approx([phi, 3 * phi, 0.0], rel=0.05, abs=1e-6), (total, phi)


def test_furnace_indirect_light_at_every_pixel_is_the_closed_form(furnace):
    """What `photon` adds to `shadows` at each pixel is a / pi * Phi / A * (a + a^2 + a^3)."""
    _, area, frame, shadows, _ = furnace
    hdr = frame.aux["hdr"][..., :3].astype(np.float64)
    indirect = hdr - shadows.aux["hdr"][..., :3].astype(np.float64)
    seen = frame.depth > 0
    assert seen.all()  # the sphere is closed: every pixel sees its inside
    a = SHELL_ALBEDO
    expected = a / np.pi * 4 * np.pi * INTENSITY / area * bounce_series(a, FURNACE_BOUNCES)
    # the direct light is the shadow rays' alone: rayvr's BRDF (Fresnel-weighted diffuse and a
    # rough lobe) at normal incidence times I / d^2, d ~ 1 (the facets lie up to 0.5 % closer)
    normal = np.array([[0.0, 0.0, 1.0]])
    f_cos = brdf_cos(normal, normal, normal, np.full((1, 3), a), np.zeros(1), np.ones(1))[0, 0]
    direct = shadows.aux["hdr"][..., 0].astype(np.float64)
    assert direct.mean() == pytest.approx(f_cos * INTENSITY, rel=0.01)
    got = indirect[..., 0]
    # photons per disc: paths * (a + a^2 + a^3) * (pi r^2 / A) ~ 870 -> 3.4 % per pixel; the
    # view covers ~15 independent discs, so the mean's tolerance (5 %) is ~5 of its sigmas
    per_disc = FURNACE_PATHS * bounce_series(a, FURNACE_BOUNCES) * np.pi * FURNACE_RADIUS ** 2 / area
    sigma = 1 / np.sqrt(per_disc)
    assert got.mean() == pytest.approx(expected, rel=1.5 * sigma), (got.mean() / expected - 1, sigma)
    assert np.abs(got / expected - 1).max() < 5 * sigma, (np.abs(got / expected - 1).max(), sigma)
    assert np.array_equal(indirect[..., 0], indirect[..., 1]) and np.array_equal(indirect[..., 0], indirect[..., 2])


# --- glossy caustic ------------------------------------------------------------------------------
METAL_ROUGHNESS = 0.6  # GGX alpha 0.36: the lobe keeps ~80 % at 45 degrees (G2 / G1 matters)
FLOOR_ALBEDO = 0.01  # photons that bounce off the floor again are too few to matter
FLOOR_X, FLOOR_Z = (-2.0, 0.0), (-1.5, 1.5)
CAUSTIC_PATHS = 1 << 18
CAUSTIC_RADIUS = 0.1
BEAM = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)  # the directional light's direction, irradiance 1
WALL_NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall: x = 0, y in [0, 1], z in [-1, 1]


def caustic_scene():
    (x0, x1), (z0, z1) = FLOOR_X, FLOOR_Z
    floor = quad(((x0 + x1) / 2, 0, (z0 + z1) / 2), ((x1 - x0) / 2, 0, 0), (0, 0, (z0 - z1) / 2))  # faces +y
    wall = quad((0, 0.5, 0), (0, 0, 1), (0, 0.5, 0))  # faces -x
    v, f, part = merge(floor, wall)
    mats = [Material("floor", base_color=(FLOOR_ALBEDO,) * 3 + (1,), roughness=1.0),
            Material("wall", base_color=(1, 1, 1, 1), metallic=1.0, roughness=METAL_ROUGHNESS)]
    return from_arrays(v, f, triangle_material=part, materials=mats,
                       lights=[Light("directional", direction=tuple(BEAM), intensity=1.0)])


def wall_grid(ny=16, nz=32):
    """Midpoints of the wall's cells (world) and a cell's area."""
    y = (np.arange(ny) + 0.5) / ny
    z = (np.arange(nz) + 0.5) / nz * 2 - 1
    pts = np.stack(np.broadcast_arrays(0.0, y[:, None], z[None, :]), -1).reshape(-1, 3)
    return pts, 2.0 / (ny * nz)


def reflected_lobe(n_mu=200, n_phi=200):
    """Directions l about the wall's normal and the weight f(w, l) cos(l) dl of each, rayvr's BRDF
    lit from w (towards the light): the share of the wall's irradiance going out along l."""
    mu = (np.arange(n_mu) + 0.5) / n_mu
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    s = np.sqrt(1 - mu * mu)
    tangent, bitangent = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    l = (mu[:, None, None] * WALL_NORMAL + (s[:, None] * np.cos(phi))[..., None] * tangent
         + (s[:, None] * np.sin(phi))[..., None] * bitangent).reshape(-1, 3)
    p = len(l)
    w = np.broadcast_to(-BEAM, l.shape)
    f_cos = brdf_cos(np.broadcast_to(WALL_NORMAL, l.shape), w, l, np.ones((p, 3)), np.ones(p),
                     np.full(p, METAL_ROUGHNESS))[:, 0]
    return l, f_cos * (1.0 / n_mu) * (2 * np.pi / n_phi)


def caustic_power_on_floor(x_edges, z_edges):
    """Power the wall reflects onto each floor cell (numpy): every wall cell, lit by E cos 45,
    sends the lobe's weights along its directions; those that reach the floor plane inside the
    floor land in the cell they hit."""
    l, weight = reflected_lobe()
    down = l[:, 1] < 0
    l, weight = l[down], weight[down]
    irradiance = float(np.dot(WALL_NORMAL, -BEAM))  # E cos 45
    pts, cell_area = wall_grid()
    power = np.zeros((len(x_edges) - 1, len(z_edges) - 1))
    for p in pts:
        t = -p[1] / l[:, 1]
        h, _, _ = np.histogram2d(p[0] + t * l[:, 0], p[2] + t * l[:, 2], bins=(x_edges, z_edges), weights=weight)
        power += h
    return power * irradiance * cell_area


def caustic_irradiance(q):
    """Irradiance the wall reflects onto floor points q (N, 3) (numpy): over the wall's cells,
    E cos 45 f(w, l) cos(wall, l) cos(floor, l) / d^2 dA."""
    pts, cell_area = wall_grid(32, 64)
    d = q[:, None, :] - pts[None, :, :]
    dist2 = (d * d).sum(-1)
    l = (d / np.sqrt(dist2)[..., None]).reshape(-1, 3)
    p = len(l)
    f_cos = brdf_cos(np.broadcast_to(WALL_NORMAL, l.shape), np.broadcast_to(-BEAM, l.shape), l, np.ones((p, 3)),
                     np.ones(p), np.full(p, METAL_ROUGHNESS))[:, 0].reshape(dist2.shape)
    cos_floor = -l[:, 1].reshape(dist2.shape)
    return float(np.dot(WALL_NORMAL, -BEAM)) * (f_cos * cos_floor / dist2).sum(1) * cell_area


def disc_average(q, radius, rings=2, spokes=8):
    """The estimate's expectation at floor points q: the irradiance averaged over the disc of the
    search radius about each (midpoint rule in r^2 and angle)."""
    total = np.zeros(len(q))
    for i in range(rings):
        rho = radius * np.sqrt((i + 0.5) / rings)
        for k in range(spokes):
            a = 2 * np.pi * (k + 0.5 * (i % 2)) / spokes
            total += caustic_irradiance(q + rho * np.array([np.cos(a), 0.0, np.sin(a)]))
    return total / (rings * spokes)


@pytest.fixture(scope="module")
def caustic(gl):
    scene = caustic_scene()
    config = {"default": "raster", "materials": {
        "floor": {"effect": "photon", "photons": CAUSTIC_PATHS, "radius": CAUSTIC_RADIUS, "bounces": 1,
                  "area_samples": 1},
        "wall": {"effect": "glossy"}}}
    rig = StereoRig(Pose.look_at((-1.0, 3.0, 0.0), (-1.0, 0.0, 0.0), up=(1.0, 0.0, 0.0)), ipd=0.0, fov_y=40,
                    size=(40, 30))
    frame, shadows, records = render_twice(gl, scene, config, rig)
    return scene, frame, shadows, records


def test_glossy_caustic_photons_land_where_the_brdf_sends_them(caustic):
    """The photons stored on the floor, binned, carry the power numpy's integral of the BRDF over
    the wall sends to each bin: in all within 2 % (~1.4 % is 3 sigma of 21k photons), and per bin
    within its Poisson error. Without G2 / G1 the photons would carry ~20 % too much."""
    scene, _, _, ph = caustic
    stored = ph["extra"] != 0
    pos = ph["position"][stored].astype(np.float64) + scene.origin
    power = ph["power"][stored, 0].astype(np.float64)
    assert np.abs(pos[:, 1]).max() < 1e-4  # all on the floor: the wall stores nothing, no first hits
    x_edges, z_edges = np.linspace(*FLOOR_X, 9), np.linspace(*FLOOR_Z, 7)
    expected = caustic_power_on_floor(x_edges, z_edges)
    got, _, _ = np.histogram2d(pos[:, 0], pos[:, 2], bins=(x_edges, z_edges), weights=power)
    count, _, _ = np.histogram2d(pos[:, 0], pos[:, 2], bins=(x_edges, z_edges))
    assert stored.sum() > 15000 and count.min() > 30
    assert got.sum() == pytest.approx(expected.sum(), rel=0.02), (got.sum(), expected.sum())
    rel = got / expected - 1
    assert (np.abs(rel) < 4.5 / np.sqrt(count) + 0.02).all(), rel.round(3)


def test_glossy_caustic_on_the_floor_pixels_is_numpys(caustic):
    """What `photon` adds to `shadows` on floor pixels near the wall, as irradiance (times pi /
    albedo), equals numpy's irradiance averaged over the search disc: per pixel within its
    photons' Poisson error, on average within 3.5 % (seeds give about +-1 %). There the light
    leaves the wall at grazing angles, where G2 / G1 weighs most: without it, +8 %."""
    _, frame, shadows, ph = caustic
    indirect = frame.aux["hdr"][..., 0].astype(np.float64) - shadows.aux["hdr"][..., 0].astype(np.float64)
    pos = frame.aux["position"][..., :3].astype(np.float64)  # world
    # discs clear of the wall (x = 0) and of the floor's edges, which cut them
    near = ((frame.aux["material"] == 0) & (frame.depth > 0) & (pos[..., 0] > -0.6) & (pos[..., 0] < -0.15)
            & (np.abs(pos[..., 2]) < 1.0))
    rows, cols = np.nonzero(near)
    assert len(rows) > 150
    pick = np.linspace(0, len(rows) - 1, 64).astype(int)
    q = pos[rows[pick], cols[pick]] * [1.0, 0.0, 1.0]
    expected = disc_average(q, CAUSTIC_RADIUS)
    got = indirect[rows[pick], cols[pick]] * np.pi / FLOOR_ALBEDO
    stored = ph["extra"] != 0
    mean_power = ph["power"][stored, 0].astype(np.float64).mean()
    sigma = 1 / np.sqrt(expected * np.pi * CAUSTIC_RADIUS ** 2 / mean_power)  # photons per disc
    rel = got / expected - 1
    assert abs(rel.mean()) < 0.035, rel.mean()
    assert (np.abs(rel) < 5 * sigma).all(), np.c_[q[:, [0, 2]], rel, sigma].round(3)


# --- periscope: a caustic through two mirrors ------------------------------------------------------
PERISCOPE_PATHS = 1 << 17
PERISCOPE_RADIUS = 0.08
PERISCOPE_SPOT = ((0.75, 1.25), (-0.5, 0.5))  # x, z under the second mirror: the beam, shifted by 1


def periscope_scene():
    """Light straight down onto mirror A (45 degrees, facing up and +x), which sends the beam along
    +x to mirror B (parallel to A, facing down and -x), which sends it down onto the floor under
    B, where nothing else lights it (B shadows it). White metal: F = 1 at both mirrors, and the
    beam keeps its cross-section: irradiance E in the spot."""
    floor = quad((0.5, 0, 0), (1.5, 0, 0), (0, 0, -1))  # x in [-1, 2], z in [-1, 1], faces +y
    along = np.array([0.25, -0.25, 0.0])  # the mirrors' slope: x + y constant
    mirror_a = quad((0.0, 1.0, 0.0), (0, 0, 0.5), along)  # cross((0, 0, .5), along) ~ (1, 1, 0)
    mirror_b = quad((1.0, 1.0, 0.0), along, (0, 0, 0.5))  # ~ (-1, -1, 0)
    v, f, part = merge(floor, mirror_a, mirror_b)
    metal = dict(base_color=(1, 1, 1, 1), metallic=1.0, roughness=0.0)
    mats = [Material("floor", base_color=(FLOOR_ALBEDO,) * 3 + (1,), roughness=1.0),
            Material("mirror_a", **metal), Material("mirror_b", **metal)]
    return from_arrays(v, f, triangle_material=part, materials=mats,
                       lights=[Light("directional", direction=(0.0, -1.0, 0.0), intensity=1.0)])


def test_a_caustic_through_two_mirrors_is_stored_with_one_bounce(gl):
    """`bounces` counts the photons a path stores on diffuse surfaces; mirror reflections on the way
    are free (frame/effects/photon/trace.py: 'having passed through any number of mirror/glossy
    reflections'). With bounces = 1, the periscope's caustic must reach the floor: every photon
    path that meets mirror A stores one photon in the spot, of the beam's power over A
    (E x 0.5 m^2 in all), and the pixels there show irradiance E. (A floor -> mirror -> floor path
    stores one too, now: the floor's own light in a mirror.) It used to stop after the
    second mirror: its reflections counted against the stores, and the spot stayed black."""
    scene = periscope_scene()
    config = {"default": "raster", "materials": {
        "floor": {"effect": "photon", "photons": PERISCOPE_PATHS, "radius": PERISCOPE_RADIUS, "bounces": 1,
                  "area_samples": 1},
        "mirror*": {"effect": "reflections"}}}
    rig = StereoRig(Pose.look_at((1.0, 0.7, 1.4), (1.0, 0.0, 0.0)), ipd=0.0, fov_y=40, size=(40, 30))
    frame, shadows, ph = render_twice(gl, scene, config, rig)
    (x0, x1), (z0, z1) = PERISCOPE_SPOT
    stored = ph["extra"] != 0
    pos = ph["position"][stored].astype(np.float64) + scene.origin
    in_spot = (pos[:, 0] > x0 - 1e-4) & (pos[:, 0] < x1 + 1e-4) & (np.abs(pos[:, 2]) < z1 + 1e-4)
    assert in_spot.sum() > 1000 and np.abs(pos[:, 1]).max() < 1e-4
    spot_area = (x1 - x0) * (z1 - z0)
    power = ph["power"][stored, 0].astype(np.float64)
    assert power[in_spot].sum() == pytest.approx(1.0 * spot_area, rel=0.03)  # ~1 % Poisson error
    # elsewhere only the floor's own light seen in a mirror (albedo 0.01): a few photons
    assert power[~in_spot].sum() < 0.01 * spot_area
    indirect = frame.aux["hdr"][..., 0].astype(np.float64) - shadows.aux["hdr"][..., 0].astype(np.float64)
    p = frame.aux["position"][..., :3].astype(np.float64)
    inner = ((frame.aux["material"] == 0) & (p[..., 0] > x0 + PERISCOPE_RADIUS) & (p[..., 0] < x1 - PERISCOPE_RADIUS)
             & (p[..., 2] > z0 + PERISCOPE_RADIUS) & (p[..., 2] < z1 - PERISCOPE_RADIUS))
    assert inner.sum() > 30
    irradiance = indirect[inner] * np.pi / FLOOR_ALBEDO
    sigma = 1 / np.sqrt(in_spot.sum() / spot_area * np.pi * PERISCOPE_RADIUS ** 2)  # photons per disc
    assert irradiance.mean() == pytest.approx(1.0, rel=2 * sigma), (irradiance.mean(), sigma)
    assert np.abs(irradiance - 1.0).max() < 5 * sigma
