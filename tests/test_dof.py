"""Thin-lens depth of field through screen-space rays (frame/passes/dof.py, glsl/post/dof.comp; Widmer
et al. 2015 §5.2). Analytic checks on the step scene (a quad at view depth ~4 in front of a wall at
~6): focused on the wall, every lens ray through a wall point in focus meets it there, so wall
pixels away from the quad keep their colour exactly; the out-of-focus quad's edge blurs into the
wall over the thin lens's circle of confusion; a vanishing aperture is the pinhole image; IPD 0
gives identical eyes. The GPU gather equals the numpy reference (frame/passes/dof.py gather_reference)."""

import numpy as np
import pytest

from conftest import run_rayvr
from test_quadtree import scenes
from rayvr.frame.cameras.rig import StereoRig
from rayvr.renderer import Renderer, RenderSettings


def binary_dilation(mask, iterations):
    """Square (8-neighbour) dilation by `iterations` pixels."""
    out = mask.copy()
    for _ in range(iterations):
        m = np.pad(out, 1)
        out = np.zeros_like(out)
        for dy in (0, 1, 2):
            for dx in (0, 1, 2):
                out |= m[dy:dy + mask.shape[0], dx:dx + mask.shape[1]]
    return out


def render(gl, scene, rig, **dof):
    with Renderer(scene, None, gl=gl, settings=RenderSettings(**dof)) as r:
        frame = r.render(rig, aux=("hdr", "depth"))
        return frame, r.compiled().pass_names


def test_depth_of_field_focus_and_blur(gl):
    scene, rig = scenes()["step"]
    sharp, passes = render(gl, scene, rig)
    assert "dof" not in passes
    wall_depth = float(np.median(sharp.left.depth[sharp.left.depth > 5.5]))
    tiny, passes = render(gl, scene, rig, dof_diameter=1e-5, dof_focus=wall_depth, dof_samples=4)
    assert passes.index("quadtree") < passes.index("dof") < passes.index("tonemap")
    assert np.abs(tiny.left.aux["hdr"] - sharp.left.aux["hdr"]).max() < 1e-3
    aperture = 2.5  # a circle of confusion of ~2.4 pixels on the quad (29 rows)
    blur, _ = render(gl, scene, rig, dof_diameter=aperture, dof_focus=wall_depth, dof_samples=64)
    a, b = blur.left.aux["hdr"], sharp.left.aux["hdr"]
    assert np.isfinite(a).all() and np.isfinite(blur.right.aux["hdr"]).all()
    depth = sharp.left.depth
    quad = (depth > 0) & (depth < 5.0)
    wall = depth > 5.5
    # Circle of confusion of the quad (depth ~4) focused at the wall, in pixels: aperture x
    # |1 - d_focus / d| / d_focus x pixels per unit of tangent ... with the thin-lens relation
    # its half-width on screen is (aperture / 2) |1/d - 1/d_focus| x pixels per tangent unit.
    cam_l, cam_r, _, _ = rig.eyes()[0].tangents
    ppt = rig.size[0] / (cam_r - cam_l)
    coc = 0.5 * aperture * abs(1 / 4.0 - 1 / wall_depth) * ppt
    near_quad = binary_dilation(quad, iterations=int(np.ceil(coc)) + 1)
    far_wall = wall & ~near_quad
    assert far_wall.sum() > 100
    assert np.abs(a[far_wall] - b[far_wall]).max() < 1e-3            # in focus: unchanged
    edge = quad & binary_dilation(~quad, 1)                            # the quad's border pixels
    changed = np.abs(a - b).max(-1) > 1e-3
    assert changed[edge].mean() > 0.5                                  # out of focus: blurred
    assert not changed[~near_quad].any()                               # and nothing beyond the CoC
    zero = StereoRig(rig.pose, ipd=0.0, fov_y=60, size=rig.size)
    z, _ = render(gl, scene, zero, dof_diameter=aperture, dof_focus=wall_depth, dof_samples=8)
    assert np.array_equal(z.left.aux["hdr"], z.right.aux["hdr"])


def test_bad_dof_settings_are_one_line_errors(tmp_path):
    with pytest.raises(ValueError, match="dof_diameter"):
        RenderSettings(dof_diameter=-1.0)
    with pytest.raises(ValueError, match="dof_focus"):
        RenderSettings(dof_focus=0.0)
    run = run_rayvr("capture", "--dof-diameter", "-2", "--out", tmp_path, timeout=60)
    assert run.returncode == 2 and "Traceback" not in run.stderr and "--dof-diameter" in run.stderr


def test_gpu_gather_equals_numpy_reference(gl):
    """dof.comp against frame/passes/dof.py gather_reference (numpy: the same lens points from the
    surface's random stream, lens rays traced by the numpy quadtree traversal) on the step scene's
    left eye, from the frame's own G-buffer, tree and colour: per pixel the same mean colour
    (float32 vs float64 traces may pick the neighbouring pixel for a ray exactly on an edge: a few
    pixels may differ)."""
    from rayvr.accel import quadtree as qt
    from rayvr.frame.passes import scene_radiance
    from rayvr.frame.passes.dof import gather_reference

    scene, rig = scenes()["step"]
    settings = RenderSettings(dof_diameter=2.5, dof_focus=5.8, dof_samples=3, seed=7)
    with Renderer(scene, None, gl=gl, settings=settings) as r:
        r.render(rig, aux=())
        w, h = rig.size
        name, fmt = scene_radiance(r.compiled().plan)
        dtype = np.float16 if fmt == "rgba16f" else np.float32
        src = np.frombuffer(r.resource(name).read(), dtype).reshape(2, h, w, 4).astype(np.float64)
        got = np.frombuffer(r.resource("hdr_dof").read(), np.float32).reshape(2, h, w, 4)[0, ..., :3]
        pos = np.frombuffer(r.resource("gbuffer").textures["position"].read(), np.float32).reshape(2, h, w, 4)[0]
        flat = np.frombuffer(r.resource("quadtree").read(), np.uint32).reshape(-1, 2)
        levels = qt.unflatten(flat[:qt.level_offsets(qt.level_sizes(w, h))[1]], (w, h))
        cam = qt.ScreenCamera.from_eye(rig.eyes()[0], r.scene.origin)
    ref = gather_reference(src[0], pos, levels, cam, 2.5, 5.8, 3, seed=7)
    assert np.isfinite(got).all()
    close = np.abs(got - ref).max(-1) <= 1e-3 * (1 + np.abs(ref).max(-1))
    assert close.mean() >= 0.98, (close.mean(), np.abs(got - ref).max())
    assert (np.abs(ref - src[0, ..., :3]).max(-1) > 1e-3).mean() > 0.2   # the blur changes pixels (38 % here)
