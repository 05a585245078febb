"""The GPU's direct lighting against an independent numpy reference (rayvr/reference/shading.py).

Each case renders the left eye on the GPU (aux "hdr": linear colour before tone mapping, from a
float16 target) and the same EyeView with the numpy reference, then compares the pixels whose
triangle IDs agree (silhouette pixels may be covered by different triangles).

Error measure, per colour channel c: the mean absolute error over the compared hit pixels divided
by the reference's mean *reflected* radiance there (hdr minus emission: the visible emitter is 12x
brighter than anything it lights and would otherwise hide errors in the shading), and a per-pixel
relative error |gpu - ref| / (ref + scale_c) whose 99th percentile is bounded (a few outliers
allowed: sharp highlights, penumbra noise). Tolerances and the measurements behind them below.
"""
import numpy as np
import pytest

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.scene.materials import parse_config
from rayvr.reference.shading import light_samples, shade_eye
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays, load
from rayvr.scene.light_selection import SHADOW_PROBES

SIZE = (64, 48)
AMBIENT = (0.10, 0.08, 0.06)       # large enough that a wrong ambient term fails the mean check
BACKGROUND = (0.1, 0.2, 0.3)

# Tolerances, as fractions of the mean reflected radiance (per channel).
# raster: both sides are deterministic (the same 4x4 points on rect lights); what remains is the
#   float16 G-buffer and HDR target (llvmpipe truncates to half: up to 1e-3 relative, a -0.1 % bias)
#   and float32 against float64. Measured mean error 0.06-0.35 % (room highest: its gold sphere's
#   highlight, which the half-float normal dims); 1 % leaves 3x margin and still catches a 2 % bias.
# shadows: adds Monte Carlo noise on rect lights (GPU: 64-point shifted lattice per pixel; numpy: 64
#   jittered-stratified points, its own seed). Measured 0.25-1.2 % over five seed pairs (the room's
#   glossy floor reflecting the light is the noisiest); 3 % is 2.5x that, and an ambient term 20 %
#   off already moves the mean by 2-13 %.
# Per pixel, 99th percentile of |gpu - ref| / (ref + scale): raster 0.5 % (measured <= 0.09 %; two
#   truncations to half precision can make 0.2 %; a 3x3 instead of 4x4 raster grid makes 0.86 %),
#   shadows 10 % (measured <= 3.7 %: penumbrae and glossy highlights at 64 samples). Point and
#   directional lights have no sampling noise: they must match like raster (measured 0.1 %).
MEAN_TOL = {"raster": 0.01, "shadows": 0.03}
P99_TOL = {"raster": 0.005, "shadows": 0.10}
RECT_SAMPLES = 64                  # GPU area_samples and numpy points per rect light per pixel
MIN_ROUGHNESS = 0.2                # compared surfaces (see _compare)


def _render(gl, scene, rig, effect, seed=1, probes=0):
    config = parse_config({"default": effect, "params": {"shadows": {"area_samples": RECT_SAMPLES}}},
                          "<test_numpy_shading>")
    # by default every shadow ray traced (shadow_probes 0), as the numpy reference takes them all
    settings = RenderSettings(ambient=AMBIENT, background=BACKGROUND, seed=seed, shadow_probes=probes)
    with Renderer(scene, config, gl=gl, settings=settings) as r:
        frame = r.render(rig, eyes="left", aux=("hdr", "triangle"))
    triangle = frame.left.aux["triangle"].astype(np.int64)
    triangle[triangle == 0xFFFFFFFF] = -1
    return frame.left.aux["hdr"].astype(np.float64), triangle


def _compare(gl, scene, rig, effect, probes=0):
    """GPU and numpy images plus the error statistics of the compared pixels.

    Surfaces with roughness < MIN_ROUGHNESS (the room's mirrors and glass) are left out: their GGX
    lobe (alpha down to 1e-3) is as narrow as the error of the G-buffer's float16 normal (~1e-3), so
    a highlight's value there depends on the rounding; and point samples of a rect light estimate a
    near-delta lobe with unbounded variance as alpha -> 0."""
    gpu, gpu_tri = _render(gl, scene, rig, effect, probes=probes)
    ref = shade_eye(scene, rig.eye("left"), effect, ambient=AMBIENT, background=BACKGROUND,
                    rect_samples=RECT_SAMPLES, seed=12345)
    assert gpu.shape == ref["hdr"].shape
    same = gpu_tri == ref["triangle"]
    assert same.mean() > 0.97, "GPU raster and numpy BVH see different triangles"
    bg = same & (ref["triangle"] < 0)
    assert np.allclose(gpu[bg], BACKGROUND, rtol=1e-3)
    rough = np.array([m.roughness for m in scene.materials])[ref["material"]]
    cmp = same & (ref["triangle"] >= 0) & (rough >= MIN_ROUGHNESS)
    emission = np.array([m.emission for m in scene.materials], np.float64)[ref["material"][cmp]]
    r, g = ref["hdr"][cmp], gpu[cmp]
    scale = (r - emission).mean(axis=0)
    err = np.abs(g - r)
    stats = {"mean": err.mean(axis=0) / scale,
             "p99": np.percentile((err / (r + scale)).max(axis=1), 99),
             "pixels": int(cmp.sum()), "scale": scale}
    return gpu, ref, cmp, stats


def _check(stats, tolerance):
    msg = f"{tolerance} tolerances: {stats}"
    assert stats["pixels"] > 500, msg
    assert np.all(stats["mean"] <= MEAN_TOL[tolerance]), msg
    assert stats["p99"] <= P99_TOL[tolerance], msg


# ------------------------------------------------------------------------------ the reference itself

def test_reference_rect_light_converges_to_the_polygon_irradiance():
    """The reference's rect-light samples integrate to the closed-form irradiance of a uniform
    polygonal emitter (Lambert: E = L/2 sum_i angle_i (n . unit(a_i x a_(i+1)))); the raster grid
    is an approximation of the same integral."""
    light = Light("rect", (1.0, 1.0, 1.0), 3.0, position=(0.2, 2.0, -0.1), u=(0.6, 0.0, 0.0), v=(0.0, 0.1, 0.4))
    p = np.array([[0.3, 0.0, 0.2], [-0.7, 0.3, 0.5], [1.5, 0.1, -0.4]])
    n = np.array([[0.0, 1.0, 0.0], [0.3, 1.0, 0.0], [-0.5, 1.0, 0.2]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    c, u, v = (np.asarray(x) for x in (light.position, light.u, light.v))
    corners = [c - u - v, c + u - v, c + u + v, c - u + v]
    exact = np.zeros(len(p))
    for a, b in zip(corners, corners[1:] + corners[:1]):
        ea = (a - p) / np.linalg.norm(a - p, axis=1, keepdims=True)
        eb = (b - p) / np.linalg.norm(b - p, axis=1, keepdims=True)
        g = np.cross(ea, eb)
        exact += np.arccos(np.sum(ea * eb, axis=1)) * np.sum(n * g, axis=1) / np.linalg.norm(g, axis=1)
    exact = np.abs(exact) * light.intensity / 2.0

    def irradiance(effect, samples, seed=0):
        rng = np.random.default_rng(seed)
        return sum(np.sum(n * l, axis=1) * e[:, 0]
                   for l, _, e in light_samples(light, np.zeros(3), p, effect, samples, rng))

    assert np.allclose(irradiance("shadows", 1024), exact, rtol=2e-3)
    assert np.allclose(irradiance("shadows", 16, seed=1), exact, rtol=5e-2)
    assert np.allclose(irradiance("raster", None), exact, rtol=2e-2)


# ------------------------------------------------------------------------------ the default room

@pytest.mark.parametrize("effect", ["raster", "shadows"])
def test_default_room_matches_numpy_reference(gl, effect):
    scene = load()
    rig = StereoRig.for_scene(scene, size=SIZE)
    _, _, _, stats = _compare(gl, scene, rig, effect)
    _check(stats, effect)


def test_adaptive_shadows_match_numpy_reference_too(gl):
    """The default adaptive shadows (64 points a pixel: 16 probes first) hold the same tolerances
    against the numpy reference that traces all 64."""
    scene = load()
    rig = StereoRig.for_scene(scene, size=SIZE)
    _, _, _, stats = _compare(gl, scene, rig, "shadows", probes=SHADOW_PROBES.default)
    _check(stats, "shadows")


# ------------------------------------------------------------------------------ Cornell box

def cornell_box():
    """A 2x2x2 box open towards +z, red left and green right walls, a 0.5x0.5 emissive panel just
    under the ceiling (the loader makes it a rect light) and a tall block that shadows the floor."""
    parts = [
        quad([0, 0, 0], [1, 0, 0], [0, 0, -1]),              # floor
        quad([0, 2, 0], [1, 0, 0], [0, 0, 1]),               # ceiling
        quad([0, 1, -1], [1, 0, 0], [0, 1, 0]),              # back
        quad([-1, 1, 0], [0, 1, 0], [0, 0, 1]),              # left (red)
        quad([1, 1, 0], [0, 0, 1], [0, 1, 0]),               # right (green)
        quad([0, 1.98, 0], [0.25, 0, 0], [0, 0, 0.25]),      # light panel, front face down
    ]
    bc, bh, bs = np.array([-0.35, 0.6, -0.3]), 0.6, 0.25   # tall block: centre, half height, half side
    for axis, sign in ((0, 1), (0, -1), (2, 1), (2, -1)):
        n = np.zeros(3)
        n[axis] = sign
        side = np.cross([0, 1, 0], n) * bs
        parts.append(quad(bc + n * bs, side, [0, bh, 0]))
    parts.append(quad(bc + [0, bh, 0], [bs, 0, 0], [0, 0, -bs]))
    v, f, part = merge(*parts)
    materials = [
        Material("white", (0.73, 0.73, 0.70, 1.0), 0.0, 0.8),
        Material("back", (0.70, 0.70, 0.72, 1.0), 0.0, 0.35),
        Material("red", (0.63, 0.06, 0.05, 1.0), 0.0, 0.9),
        Material("green", (0.12, 0.45, 0.09, 1.0), 0.0, 0.9),
        Material("light", (0.8, 0.8, 0.8, 1.0), 0.0, 0.9, emission=(17.0, 12.0, 4.0)),
        Material("block", (0.90, 0.60, 0.30, 1.0), 1.0, 0.4),  # metal: F0 = base colour
    ]
    part_material = [0, 0, 1, 2, 3, 4] + [5] * 5
    scene = from_arrays(v, f, triangle_material=np.asarray(part_material)[part], materials=materials,
                        name="cornell")
    assert [l.kind for l in scene.lights] == ["rect"] and scene.lights[0].intensity == 17.0
    assert np.cross(scene.lights[0].u, scene.lights[0].v)[1] < 0  # emits downwards
    rig = StereoRig(Pose.look_at([0, 1, 3.8], [0, 1, 0]), fov_y=40.0, size=SIZE)
    return scene, rig


@pytest.mark.parametrize("effect", ["raster", "shadows"])
def test_cornell_box_matches_numpy_reference(gl, effect):
    scene, rig = cornell_box()
    gpu, ref, cmp, stats = _compare(gl, scene, rig, effect)
    _check(stats, effect)
    if effect == "shadows":  # the block's shadow is really there, on both sides
        floor = cmp & (ref["material"] == 0) & (np.arange(SIZE[1])[:, None] > SIZE[1] * 0.6)
        dark = floor & (ref["hdr"][..., 0] < 0.5 * np.median(ref["hdr"][..., 0][floor]))
        assert dark.sum() >= 10
        assert np.median(gpu[..., 0][dark]) < 0.6 * np.median(gpu[..., 0][floor & ~dark])


# ------------------------------------------------------------------------------ hard shadows

def plane_and_occluder(light):
    """A 6x6 ground plane and a floating 1.2x0.2x1.0 slab above it, lit by one light."""
    parts = [quad([0, 0, 0], [3, 0, 0], [0, 0, -3])]
    c, h = np.array([0.2, 1.0, 0.0]), np.array([0.6, 0.1, 0.5])
    for axis in range(3):
        for sign in (1, -1):
            n = np.zeros(3)
            n[axis] = sign
            a, b = np.eye(3)[(axis + 1) % 3] * h, np.eye(3)[(axis + 2) % 3] * h
            parts.append(quad(c + n * h, a, b) if sign > 0 else quad(c + n * h, b, a))
    v, f, part = merge(*parts)
    materials = [Material("ground", (0.6, 0.6, 0.6, 1.0), 0.0, 0.7),
                 Material("slab", (0.3, 0.5, 0.8, 1.0), 0.0, 0.5)]
    scene = from_arrays(v, f, triangle_material=np.minimum(part, 1), materials=materials, lights=[light],
                        name=f"plane_{light.kind}")
    rig = StereoRig(Pose.look_at([0.3, 3.2, 2.4], [0.3, 0, -0.2]), fov_y=60.0, size=SIZE)
    return scene, rig


HARD_LIGHTS = {
    "point": Light("point", (1.0, 0.9, 0.8), 8.0, position=(-0.8, 2.2, 0.9)),
    "directional": Light("directional", (1.0, 0.95, 0.9), 2.5, direction=(0.7, -1.0, 0.6)),
}


def _lit(shadows, raster, ground):
    """Ground pixels the light reaches: the `shadows` image keeps (nearly) all of the `raster`
    image's direct light there, and none of it in the shadow (hard shadows: 0 or 1)."""
    ambient = np.multiply(AMBIENT, 0.6)[0]
    return ground & (shadows[..., 0] - ambient > 0.5 * (raster[..., 0] - ambient))


def _near_edge(mask):
    """Pixels within one pixel (8-neighbourhood) of a change in `mask`."""
    p = np.pad(mask, 1, mode="edge")
    h, w = mask.shape
    edge = np.zeros_like(mask)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            edge |= p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] != mask
    return edge


@pytest.mark.parametrize("kind", sorted(HARD_LIGHTS))
def test_hard_shadows_match_numpy_reference_pixel_for_pixel(gl, kind):
    scene, rig = plane_and_occluder(HARD_LIGHTS[kind])
    images = {}
    for effect in ("raster", "shadows"):
        gpu, ref, cmp, stats = _compare(gl, scene, rig, effect)
        _check(stats, "raster")  # no rect light: no sampling noise, whatever the effect
        images[effect] = gpu, ref["hdr"]
    ground = cmp & (ref["material"] == 0)
    lit_gpu = _lit(images["shadows"][0], images["raster"][0], ground)
    lit_ref = _lit(images["shadows"][1], images["raster"][1], ground)
    shadow = ground & ~lit_ref
    assert shadow.sum() >= 100, "the slab's shadow should cover a good part of the ground"
    # the same pixels are in shadow, except within a pixel of the shadow's (or the ground's) edge
    edge = _near_edge(lit_ref | ~ground)
    differ = lit_ref != lit_gpu
    assert not (differ & ~edge).any(), f"{int((differ & ~edge).sum())} pixels away from the edge differ"
    assert differ.sum() <= 0.05 * shadow.sum()
    # inside the shadow: exactly the ambient term, on both sides
    inner = shadow & ~edge
    assert inner.sum() >= 50
    assert np.allclose(images["shadows"][0][inner], np.multiply(AMBIENT, 0.6), rtol=2e-3)
    assert np.allclose(images["shadows"][1][inner], np.multiply(AMBIENT, 0.6), rtol=1e-12)
