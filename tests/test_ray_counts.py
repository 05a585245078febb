"""trace_effect.count_rays: the rays each traced effect traces in one frame, counted on the GPU by
the trace kernels' counting variants (WAVE_COUNT_RAYS). Judged against what the geometry says: under
one point light every floor pixel of `shadows` casts exactly one shadow ray, and every pixel of a
mirror casts exactly one reflection ray; the counts hold on every counting frame of a renderer (on
an H100 the first version lost the pixel events' counts after the first), and counting leaves the
image as the timed kernels make it."""
from __future__ import annotations

import numpy as np

from conftest import merge, quad
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.passes.trace_effect import TraceEffectPass, count_rays
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.loader import Light, Material, from_arrays
from rayvr.scene.materials import parse_config

RIG = StereoRig(Pose.look_at((0, 3.0, 2.0), (0, 0, 0)), ipd=0.1, fov_y=60, size=(48, 32))
OTHER = StereoRig(Pose.look_at((1.0, 2.0, 2.5), (0, 0, -1)), ipd=0.1, fov_y=60, size=(48, 32))


def scene():
    """A floor (material 0) under a point light with a wall behind it (material 1) that the floor
    does not fill the view without; the light is high over the floor, so every floor point sees it."""
    v, f, part = merge(quad((0, 0, 0), (3, 0, 0), (0, 0, -3)), quad((0, 1.5, -3), (3, 0, 0), (0, 1.5, 0)))
    return from_arrays(v, f, triangle_material=part, materials=[Material("floor"), Material("wall")],
                       lights=[Light("point", intensity=5, position=(0, 2.5, 0.5))])


def config(floor_effect):
    return parse_config({"default": "raster", "materials": {"floor": floor_effect}}, "t")


def floor_pixels(frame) -> int:
    return int(sum((eye.aux["material"] == 0).sum() for eye in (frame.left, frame.right)))


def test_each_floor_pixel_casts_one_shadow_ray_on_every_counting_frame(gl):
    settings = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0), seed=3)
    with Renderer(scene(), config("shadows"), gl=gl, settings=settings) as r:
        frame = r.render(RIG, aux=("hdr", "material"))
        n = floor_pixels(frame)
        assert n > 500  # the floor fills much of the view
        counts = [count_rays(r, RIG)["shadows"] for _ in range(3)]
        r.render(RIG)  # a timed frame between counting ones
        counts.append(count_rays(r, RIG)["shadows"])
        again = r.render(RIG, aux=("hdr",))
        r.render(OTHER)
        passes = [p for p in r.compiled(r.plan(camera=RIG.camera)).passes if isinstance(p, TraceEffectPass)]
        for p in passes:
            p.count_rays = True
        counting = r.render(RIG, aux=("hdr",))
        for p in passes:
            p.count_rays = False
    # the counting kernels trace what the timed ones do: a counting frame, and the frames after
    # counting, are the image of a frame that never counted (at another pose in between, so that a
    # kernel that did not run would leave the other pose's image)
    for a, b in ((frame.left, again.left), (frame.right, again.right)):
        np.testing.assert_array_equal(a.aux["hdr"], b.aux["hdr"])
        assert a.aux["hdr"].max() > 0.05  # a lit floor, not an empty comparison
    for a, b in ((frame.left, counting.left), (frame.right, counting.right)):
        np.testing.assert_array_equal(a.aux["hdr"], b.aux["hdr"])
    for c in counts:
        assert c == {"closest": 0, "shadow": n, "pixels": n}, counts


def test_each_mirror_pixel_casts_one_reflection_ray(gl):
    settings = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0), seed=3)
    with Renderer(scene(), config("reflections"), gl=gl, settings=settings) as r:
        n = floor_pixels(r.render(RIG, aux=("material",)))
        counts = [count_rays(r, RIG)["reflections"] for _ in range(2)]
    for c in counts:
        assert c["pixels"] == n and c["closest"] == n, counts
        # a mirror pixel lights its own surface with one shadow ray, and each reflection ray that hits
        # the (lit) wall lights that hit with one more: between one and two a pixel
        assert n <= c["shadow"] <= 2 * n, counts
    assert counts[0] == counts[1]


def test_timed_frames_run_kernels_without_counters(gl):
    """The programs of a frame that does not count are not the counting variants."""
    settings = RenderSettings(ambient=(0, 0, 0), background=(0, 0, 0))
    with Renderer(scene(), config("shadows"), gl=gl, settings=settings) as r:
        count_rays(r, RIG)
        passes = [p for p in r.compiled(r.plan(camera=RIG.camera)).passes if isinstance(p, TraceEffectPass)]
        assert passes and all(p.counting for p in passes)
        for p in passes:
            timed = p.frame_programs("_every")
            assert not any(timed[name] is k for name, k in p.counting.items())
            p.count_rays = True
            try:
                counting = p.frame_programs("_every")
            finally:
                p.count_rays = False
            assert all(counting[name] is k for name, k in p.counting.items())
