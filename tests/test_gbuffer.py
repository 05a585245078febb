"""The layered stereo G-buffer against analytic geometry (runs on llvmpipe at small sizes)."""
import math

import numpy as np
import pytest
import trimesh

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.gbuffer import NO_HIT
from rayvr.scene.materials import parse_config
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Material, from_arrays, load

ALL_AUX = ("depth", "zbuffer", "position", "normal", "albedo", "material", "effect", "triangle")


def render(gl, scene, rig, materials=None, layer_mode="auto", eyes="both", aux=ALL_AUX):
    r = Renderer(scene, materials, gl=gl, settings=RenderSettings(layer_mode=layer_mode))
    try:
        return r.render(rig, eyes=eyes, aux=aux)
    finally:
        r.release()


def plane_scene(z=-4.0, size=50.0, tilt_deg=0.0):
    """A square plane through (0, 0, z) facing +Z, tilted about X."""
    a = math.radians(tilt_deg)
    v = (0.0, size * math.cos(a), size * math.sin(a))
    verts, faces = quad((0, 0, z), (size, 0, 0), v)
    return from_arrays(verts, faces, name="plane"), np.array([0.0, -math.sin(a), math.cos(a)])


def test_pixels_register_with_rays_on_a_tilted_plane(gl):
    """Every pixel's G-buffer position lies on the ray through that pixel's centre (both eyes):
    rays generated from the rig hit exactly what the rasterizer put there."""
    scene, n = plane_scene(z=-4.0, tilt_deg=35.0)
    rig = StereoRig(Pose.look_at([0.3, 0.5, 1.0], [0, 0, -4]), ipd=0.2, fov_y=70, size=(48, 36), convergence=3.0)
    frame = render(gl, scene, rig)
    p0 = np.array([0.0, 0.0, -4.0])
    for eye in rig.eyes():
        d = eye.ray_directions()
        t = ((p0 - eye.position) @ n) / (d @ n)
        expected = eye.position + t[..., None] * d
        got = frame[eye.name].aux["position"]
        assert (frame[eye.name].aux["triangle"] != NO_HIT).all()
        err = np.linalg.norm(got - expected, axis=-1) / t
        assert err.max() < 2e-5, f"{eye.name}: max relative position error {err.max():.2e}"
        view_depth = t * (d @ eye.rotation[:, 2] * -1)
        assert np.allclose(frame[eye.name].depth, view_depth, rtol=2e-5)
        normals = frame[eye.name].aux["normal"]
        assert np.allclose(normals, n, atol=2e-3)
        # reversed-Z buffer holds near / view depth
        assert np.allclose(frame[eye.name].aux["zbuffer"], rig.near / view_depth, rtol=1e-4)


def test_plane_disparity_matches_rig_geometry(gl):
    D, ipd, fov, (w, h) = 3.0, 0.4, 60.0, (96, 64)
    marker = quad((0.1, 0.05, -D), (0.25, 0, 0), (0, 0.25, 0))
    v, f, part = merge(quad((0, 0, -D - 0.5), (40, 0, 0), (0, 40, 0)), marker)
    scene = from_arrays(v, f, triangle_material=part, materials=[Material("back"), Material("marker")])
    rig = StereoRig(Pose(), ipd=ipd, fov_y=fov, size=(w, h))
    frame = render(gl, scene, rig, aux=("material",))
    centres = {}
    for eye in ("left", "right"):
        ys, xs = np.nonzero(frame[eye].aux["material"] == 1)
        assert len(xs) > 50
        centres[eye] = (xs.mean() + 0.5, ys.mean() + 0.5)
        predicted = rig.eye(eye).project([0.1, 0.05, -D])[0]
        assert centres[eye][0] == pytest.approx(predicted[0], abs=0.35)
        assert centres[eye][1] == pytest.approx(predicted[1], abs=0.35)
    focal = (h / 2) / math.tan(math.radians(fov) / 2)
    disparity = centres["left"][0] - centres["right"][0]
    assert disparity == pytest.approx(focal * ipd / D, abs=0.5)
    assert focal * ipd / D > 5  # the test resolves a real disparity


def _ray_sphere(o, d, c, r):
    oc = o - c
    b = d @ oc
    disc = b * b - (oc @ oc - r * r)
    t = -b - np.sqrt(np.maximum(disc, 0))
    return np.where(disc > 0, t, np.nan)


def test_sphere_depth_and_normals_match_analytic(gl):
    c, r = np.array([0.2, -0.1, -3.0]), 1.0
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=r)
    scene = from_arrays(sphere.vertices + c, sphere.faces, name="sphere")
    rig = StereoRig(Pose(), ipd=0.1, fov_y=60, size=(64, 64))
    frame = render(gl, scene, rig)
    for eye in rig.eyes():
        d = eye.ray_directions()
        t = _ray_sphere(eye.position, d, c, r)
        hit_analytic = np.isfinite(t)
        hit = frame[eye.name].aux["triangle"] != NO_HIT
        # Tessellation only moves the silhouette by a fraction of a pixel.
        assert (hit != hit_analytic).mean() < 0.03
        p = eye.position + np.nan_to_num(t)[..., None] * d
        n = (p - c) / r
        cos = -(d * n).sum(-1)
        inner = hit & hit_analytic & (cos > 0.3)
        view_depth = np.nan_to_num(t) * (-(d @ eye.rotation[:, 2]))
        chord = r * (1 - math.cos(0.04))  # icosphere level 5 edges span < 0.04 rad
        assert np.abs(frame[eye.name].depth[inner] - view_depth[inner]).max() < chord / 0.3 + 1e-4
        dots = (frame[eye.name].aux["normal"][inner] * n[inner]).sum(-1)
        assert dots.min() > 0.999
        assert (frame[eye.name].depth[~hit] == 0).all()


def test_effect_buffer_matches_material_config(gl):
    scene = load()
    cfg = parse_config({"default": "shadows", "materials": {"mirror*": "reflections", "gold": "glossy",
                                                            "light": "raster"}}, "test")
    rig = StereoRig.for_scene(scene, size=(64, 48))
    frame = render(gl, scene, rig, materials=cfg, aux=("material", "effect", "triangle"))
    expected_by_material = np.array([a.effect_id for a in cfg.assign(scene.material_names(), warn=False)])
    for eye in ("left", "right"):
        aux = frame[eye].aux
        hit = aux["triangle"] != NO_HIT
        assert hit.mean() > 0.9
        assert (aux["material"][hit] == scene.triangle_material[aux["triangle"][hit]]).all()
        assert (aux["effect"][hit] == expected_by_material[aux["material"][hit]]).all()
        assert len(np.unique(aux["effect"][hit])) >= 3
        assert (aux["effect"][~hit] == 255).all()


def test_layer_modes_and_mono_agree(gl):
    scene = load()
    rig = StereoRig.for_scene(scene, size=(40, 30))
    modes = ["vertex", "geometry", "passes"] + (["multiview"] if gl.has_extension("GL_OVR_multiview2") else [])
    frames = {mode: render(gl, scene, rig, layer_mode=mode) for mode in modes}
    ref = frames["vertex"]
    for mode, frame in frames.items():
        for eye in ("left", "right"):
            assert (frame[eye].aux["triangle"] == ref[eye].aux["triangle"]).all(), mode
            assert np.allclose(frame[eye].depth, ref[eye].depth, rtol=1e-6), mode
            assert np.abs(frame[eye].color.astype(int) - ref[eye].color).max() <= 1, mode
    for eye in ("left", "right"):
        mono = render(gl, scene, rig, eyes=eye)
        assert list(mono.eyes) == [eye]
        assert (mono[eye].aux["triangle"] == ref[eye].aux["triangle"]).all()
        assert np.abs(mono[eye].color.astype(int) - ref[eye].color).max() <= 1


@pytest.mark.parametrize("near, far, dist", [
    (1e-4, None, 1e-1), (1e-4, None, 1e3), (1e-2, 1e5, 1e2), (1.0, 1e7, 1e6), (1e-3, 10.0, 5.0), (10.0, None, 1e5),
])
def test_depth_precision_two_close_planes(gl, near, far, dist):
    """A plane 2e-6 * distance in front of another resolves on every pixel (no z-fighting), for
    near/far ratios from 1e-4 (and infinite far) to 1e-7."""
    eps = 2e-6
    s = dist
    v, f, part = merge(quad((0, 0, -dist * (1 + eps)), (s, 0, 0), (0, s, 0)),   # back, larger
                       quad((0, 0, -dist), (0.5 * s, 0, 0), (0, 0.5 * s, 0)))   # front, centre
    scene = from_arrays(v, f, triangle_material=part, materials=[Material("back"), Material("front")])
    rig = StereoRig(Pose.look_at([0.01 * s, 0.02 * s, 0], [0, 0, -dist]), ipd=0.0, fov_y=60, size=(32, 32),
                    near=near, far=far)
    frame = render(gl, scene, rig, eyes="left", aux=("material",))
    mat = frame.left.aux["material"]
    centre = mat[10:22, 10:22]
    assert (centre == 1).all(), f"z-fighting: {int((centre != 1).sum())} centre pixels show the back plane"
    assert (mat[0, :] == 0).all()


def test_far_from_origin_matches_near_origin(gl):
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    v, f, part = merge((sphere.vertices + [0, 0, -2], sphere.faces), quad((0, 0, -3), (8, 0, 0), (0, 8, 0)))
    off = np.array([1e5, -1e5, 1e5])
    frames = []
    for o in (np.zeros(3), off):
        scene = from_arrays(v + o, f, triangle_material=part, materials=[Material("a"), Material("b")])
        rig = StereoRig(Pose.look_at(o + [0.1, 0.2, 1.0], o + [0, 0, -2]), ipd=0.064, size=(48, 32))
        frames.append(render(gl, scene, rig))
    for eye in ("left", "right"):
        a, b = frames[0][eye], frames[1][eye]
        assert (a.aux["triangle"] == b.aux["triangle"]).mean() > 0.995
        same = (a.aux["triangle"] == b.aux["triangle"]) & (a.aux["triangle"] != NO_HIT)
        assert same.mean() > 0.5
        assert np.allclose(a.depth[same], b.depth[same], rtol=1e-5, atol=1e-6)
        assert np.abs((b.aux["position"] - off)[same] - a.aux["position"][same]).max() < 1e-4


def test_no_nan_anywhere(gl):
    scene = load()
    for rig in (StereoRig.for_scene(scene, size=(24, 16)),
                StereoRig.for_scene(scene, size=(24, 16), ipd=0.0, near=1e-6, fov_y=179.0),
                StereoRig.for_scene(scene, size=(24, 16), ipd=50.0, far=1e3)):
        for view in ("color", "depth", "normal", "effect"):
            r = Renderer(scene, gl=gl)
            frame = r.render(rig, view=view, aux=ALL_AUX)
            r.release()
            for img in frame.eyes.values():
                assert np.isfinite(img.depth).all()
                for name, arr in img.aux.items():
                    if arr.dtype.kind == "f":
                        assert np.isfinite(arr).all(), (view, name)


@pytest.mark.parametrize("wound", ["towards", "away"])
def test_file_normals_against_the_winding_shade_the_side_in_view(gl, wound):
    """A file's vertex normals may point against the triangles' winding (mirrored meshes, flipped
    exports). Shading is two-sided: the side in view gets the normal turned towards the viewer,
    whichever way the file wound it (Mitsuba's `twosided` flips by the shading normal alike), so
    such a quad under a point light shades exactly as with normals along its winding; before, the
    normal was flipped by the geometric side only and turned away: the lit quad came out black."""
    from rayvr.scene.loader import Light
    verts, faces = quad((0.0, 0.0, -3.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))  # winding faces +z
    if wound == "away":  # the camera sees the triangles' back
        faces = faces[:, ::-1]
    rig = StereoRig(Pose.look_at((0.2, 0.1, 0.0), (0.0, 0.0, -3.0)), ipd=0.06, fov_y=40, size=(24, 18))
    light = [Light("point", intensity=4.0, position=(0.5, 0.8, -1.0))]
    cfg = parse_config({"default": "raster"}, "<test>")
    out = {}
    for sign in (1.0, -1.0):
        n = np.tile([0.0, 0.0, sign], (4, 1))
        sc = from_arrays(verts, faces, normals=n, materials=[Material("m", roughness=0.6)], lights=light)
        with Renderer(sc, cfg, gl=gl, settings=RenderSettings(ambient=(0.0, 0.0, 0.0))) as r:
            f = r.render(rig, eyes="both", aux=("hdr", "normal", "material"))
        out[sign] = f
    for e in ("left", "right"):
        quad_px = out[1.0][e].aux["material"] == 0
        assert quad_px.mean() > 0.3
        for sign in (1.0, -1.0):
            nz = out[sign][e].aux["normal"][..., 2][quad_px]
            assert (nz > 0.99).all(), (sign, e, nz.min())  # towards the camera (+z)
        a, b = out[1.0][e].aux["hdr"][quad_px], out[-1.0][e].aux["hdr"][quad_px]
        assert a.mean() > 0.05 and np.array_equal(a, b)
    # the numpy reference (rayvr/reference/shading.py) turns the normal the same way
    from rayvr.reference.shading import shade_eye
    sc = from_arrays(verts, faces, normals=np.tile([0.0, 0.0, -1.0 if wound == "towards" else 1.0], (4, 1)),
                     materials=[Material("m", roughness=0.6)], lights=light)
    ref = shade_eye(sc, rig.eye("left"), "raster", ambient=(0.0, 0.0, 0.0))
    both = (ref["material"] == 0) & (out[1.0]["left"].aux["material"] == 0)
    got = out[1.0]["left"].aux["hdr"][both].astype(np.float64)
    assert np.abs(got - ref["hdr"][both]).max() < 0.01 * ref["hdr"][both].max()
