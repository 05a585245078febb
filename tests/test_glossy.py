"""The `glossy` effect (glsl/rt/wave_shade.comp, stages 3-5) against numpy: what a rough metal floor
reflects of an emitter whose extent is known, integrated by numpy quadrature of the GGX BRDF with
its own sampling scheme (D-proportional half vectors on a fixed grid; the shader draws visible
normals at random), and where a sharp floor shows a small emitter by mirror geometry."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays

DARK = RenderSettings(ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0))
WALL_X, WALL_H = 1000.0, 1.0e5


def floor_material(roughness):
    # metallic, white: Schlick F = F0 = 1 at every angle, so the reflected radiance is the GGX
    # lobe's share of the directions that reach the emitter, nothing else
    return Material("floor", base_color=(1, 1, 1, 1), metallic=1.0, roughness=roughness)


def render_floor(gl, scene, rig, samples, seed=0, eyes="left"):
    cfg = parse_config({"default": "raster", "materials": {"floor": {"effect": "glossy", "samples": samples}}}, "t")
    settings = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0), seed=seed)
    with Renderer(scene, cfg, gl=gl, settings=settings) as r:
        frame = r.render(rig, eyes=eyes, aux=("hdr", "material", "position"))
    return frame


def smith_lambda(cos_t, alpha):
    c2 = np.clip(cos_t * cos_t, 1e-12, 1.0)
    return 0.5 * (-1.0 + np.sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2))


def reflected_share(v, alpha, reaches, n_theta=96, n_phi=192):
    """For unit view vectors v (N, 3) on a floor with normal +y: the integral over the upper
    hemisphere of f(v, l) cos(l) over the directions l with reaches(l) true, for GGX (Trowbridge-
    Reitz D, height-correlated Smith G2, F = 1). Half vectors h are taken on a midpoint grid of
    the inverse of D(h) cos(h) (tan^2 = alpha^2 u / (1 - u), phi = 2 pi u2); with pdf(l) =
    D cos(h) / (4 v.h) the integrand over pdf is G2 (v.h) / (n.v n.h)."""
    u1 = (np.arange(n_theta) + 0.5) / n_theta
    u2 = (np.arange(n_phi) + 0.5) / n_phi
    tan2 = alpha * alpha * u1 / (1.0 - u1)
    cos_h = 1.0 / np.sqrt(1.0 + tan2)
    sin_h = np.sqrt(1.0 - cos_h * cos_h)
    phi = 2 * np.pi * u2
    # +y up: h = (sin cos phi, cos, sin sin phi)
    h = np.stack(np.broadcast_arrays(sin_h[:, None] * np.cos(phi), cos_h[:, None], sin_h[:, None] * np.sin(phi)), -1)
    h = h.reshape(-1, 3)
    out = np.empty(len(v))
    for k0 in range(0, len(v), 64):
        vv = v[k0:k0 + 64, None, :]
        vh = (vv * h).sum(-1)
        l = 2 * vh[..., None] * h - vv
        nv, nl, nh = vv[..., 1], l[..., 1], h[:, 1]
        g2 = 1.0 / (1.0 + smith_lambda(nv, alpha) + smith_lambda(nl, alpha))
        ok = (vh > 0) & (nl > 0) & reaches(l)
        out[k0:k0 + 64] = np.where(ok, g2 * vh / (nv * nh), 0.0).mean(-1)
    return out


@pytest.fixture(scope="module")
def half_space():
    """A rough white metal floor (y = 0) and an emitter of radiance 1 far away at x = +1000 that
    fills (almost) every upward direction with l.x > 0: what the floor reflects depends on the
    view direction only, a ramp across the image whose width is the lobe's."""
    rough = 0.3
    floor = quad((0, 0, 0), (8, 0, 0), (0, 0, -8))
    wall = quad((WALL_X, 0, 0), (0, 0, WALL_H), (0, WALL_H, 0))  # faces -x, towards the floor
    v, f, part = merge(floor, wall)
    mats = [floor_material(rough), Material("sky", base_color=(0, 0, 0, 1), emission=(1.0, 1.0, 1.0))]
    scene = from_arrays(v, f, triangle_material=part, materials=mats, lights=[Light("point", intensity=0.0)])
    rig = StereoRig(Pose.look_at((0.0, 3.0, 2.5), (0.0, 0.0, -0.5)), ipd=0.0, fov_y=50, size=(48, 36))
    eye = rig.eye("left")

    def reaches(l):  # the wall's hit test from near the origin (the floor is 8 wide, the wall 1000 away)
        return (l[..., 0] > 0) & (np.abs(l[..., 1]) * WALL_X < WALL_H * l[..., 0]) & \
               (np.abs(l[..., 2]) * WALL_X < WALL_H * l[..., 0])

    # expected per pixel, from the pixel's own ray (the floor point is found by numpy, not the GPU)
    d = eye.ray_directions()
    o = eye.position
    t = -o[1] / np.where(d[..., 1] < 0, d[..., 1], -1.0)
    p = o + t[..., None] * d
    on = (d[..., 1] < -1e-3) & (np.abs(p[..., 0]) < 7.5) & (np.abs(p[..., 2]) < 7.5)
    view = -d[on]
    expected = np.zeros(d.shape[:2])
    expected[on] = reflected_share(view, rough * rough, reaches)
    return scene, rig, on, expected


def test_half_space_expectation_is_a_ramp(half_space):
    """The numpy side alone: near 0 where the mirror direction points away from the emitter, near
    the lobe's albedo where it points at it, and a ramp between on enough pixels to test."""
    _, rig, on, expected = half_space
    assert on.sum() > 800
    assert expected[on].min() < 0.03 and expected[on].max() > 0.9
    assert ((expected > 0.15) & (expected < 0.85)).sum() > 100
    # the quadrature against a second one: a plain (cos theta, phi) grid over the hemisphere of l
    n = 400
    ct, ph = (np.arange(n) + 0.5) / n, (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    st = np.sqrt(1 - ct * ct)
    l = np.stack(np.broadcast_arrays(st[:, None] * np.cos(ph), ct[:, None], st[:, None] * np.sin(ph)), -1).reshape(-1, 3)
    alpha = 0.3 ** 2
    for theta, azimuth in ((0, 0), (40, 180), (60, 150), (75, 100)):
        t, a = np.radians(theta), np.radians(azimuth)
        v = np.array([np.sin(t) * np.cos(a), np.cos(t), np.sin(t) * np.sin(a)])
        h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
        d = alpha ** 2 / (np.pi * (h[:, 1] ** 2 * (alpha ** 2 - 1) + 1) ** 2)
        g2 = 1 / (1 + smith_lambda(v[1], alpha) + smith_lambda(l[:, 1], alpha))
        f_cos = np.where(l[:, 0] > 0, d * g2 / (4 * v[1]), 0.0)
        brute = f_cos.sum() / n * (np.pi / n)
        assert reflected_share(v[None], alpha, lambda x: x[..., 0] > 0)[0] == pytest.approx(brute, abs=0.006)


@pytest.mark.parametrize("samples", [1, 4, 64, 256])
def test_glossy_reflects_the_lobe_share_of_an_emitter(gl, half_space, samples):
    """The image is an unbiased estimate of the integral at every sample count, and its noise
    falls as 1 / samples. Each sample's weight w is in [0, 1] with mean E (the pixel's expected
    value), so a pixel's variance is at most (E - E^2) / samples: the mean squared error over the
    floor must stay under that (x 1.2 for the estimate's own scatter). A weight not divided by
    `samples`, a direction reflected about the wrong vector (the mirror's step, or rays sent
    under the floor) or a lobe of the wrong width moves the mean or the squared error."""
    scene, rig, on, expected = half_space
    frame = render_floor(gl, scene, rig, samples)
    got = frame.left.aux["hdr"][..., 0].astype(np.float64)
    assert (frame.left.aux["material"][on] == 0).mean() > 0.99  # the pixels numpy chose are floor
    sel = on & (frame.left.aux["material"] == 0)
    e, diff = expected[sel], got[sel] - expected[sel]
    sigma_mean = 0.5 / np.sqrt(samples * sel.sum())
    assert abs(diff.mean()) < 5 * sigma_mean + 0.01, f"bias {diff.mean():.4f} at {samples} samples"
    assert got[sel].max() <= 1.0 + 1e-3, f"reflected more than the emitter's radiance: {got[sel].max():.3f}"
    bound = (e * (1 - e)).mean() / samples
    assert (diff ** 2).mean() < 1.2 * bound + 1e-4, \
        f"mean squared error {(diff ** 2).mean():.2e}, noise alone allows {bound:.2e} at {samples} samples"
    ramp = sel & (expected > 0.15) & (expected < 0.85)
    if samples >= 64:  # the ramp's pixels are blends of the emitter and the dark, not a step
        assert ((got[ramp] > 0.05) & (got[ramp] < 0.95)).mean() > 0.8


def test_sharp_glossy_floor_shows_the_emitter_where_the_mirror_puts_it(gl):
    """Low roughness: the floor shows a small bright emitter at the pixels whose mirror ray (numpy)
    meets it, and nothing elsewhere; the pixel of the mirror point of the emitter's centre is lit."""
    centre, half = np.array([0.6, 1.2, -1.2]), 0.5
    floor = quad((0, 0, 0), (6, 0, 0), (0, 0, -6))
    lamp = quad(centre, (half, 0, 0), (0, 0, half))  # faces -y (cross(u, v)), towards the floor
    v, f, part = merge(floor, lamp)
    mats = [floor_material(0.05), Material("lamp", base_color=(0, 0, 0, 1), emission=(6.0, 6.0, 6.0))]
    scene = from_arrays(v, f, triangle_material=part, materials=mats, lights=[Light("point", intensity=0.0)])
    rig = StereoRig(Pose.look_at((-0.6, 1.1, 2.6), (0.5, 0.0, -1.2)), ipd=0.2, fov_y=60, size=(48, 36))
    checked = 0
    frame = render_floor(gl, scene, rig, samples=32, eyes="both")
    for e in rig.eyes():
        aux = frame[e.name].aux
        floor_px = aux["material"] == 0
        d = e.ray_directions()[floor_px]
        p = aux["position"][floor_px]
        r = d * np.array([1.0, -1.0, 1.0])  # mirror about the floor's normal +y
        t = (centre[1] - p[:, 1]) / r[:, 1]
        q = p + t[:, None] * r
        inside = half - np.maximum(np.abs(q[:, 0] - centre[0]), np.abs(q[:, 2] - centre[2]))  # > 0: on the lamp
        got = aux["hdr"][floor_px].mean(-1)
        lit, dark = inside > 0.04 * t, inside < -0.04 * t
        assert lit.sum() >= 8 and dark.sum() >= 300, (lit.sum(), dark.sum())
        # GGX has long tails (a sample leaves k alphas off the mirror with probability 1 / (1 + k^2)):
        # judged per pixel loosely, over all pixels tightly
        assert got[lit].min() > 0.6 * 6.0, f"{e.name}: the lamp's reflection is missing or dim: {got[lit].min():.3f}"
        assert got[lit].mean() > 0.9 * 6.0, f"{e.name}: the lamp's reflection is dim: {got[lit].mean():.3f}"
        assert np.median(got[dark]) == 0.0 and got[dark].mean() < 0.02 * 6.0, \
            f"{e.name}: light reflected where the mirror shows no lamp: mean {got[dark].mean():.3f}"
        assert (got[dark] > 0.3 * 6.0).mean() < 0.01
        # the mirror point: where the line from the eye to the lamp's mirror image meets the floor
        image = centre * np.array([1.0, -1.0, 1.0])
        m = e.position + (image - e.position) * (e.position[1] / (e.position[1] - image[1]))
        x, y, _ = e.project(m)[0]
        assert aux["hdr"][int(y), int(x)].mean() > 0.6 * 6.0
        checked += lit.sum() + dark.sum()
    assert checked > 600
