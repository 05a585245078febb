"""Ray-cast primary visibility with every camera model, sub-rays per sample (MSAA / SSAA for rays)
and colour channel sets, end to end through the frame graph: against numpy traces of the models'
own rays, the raster G-buffer and analytic edge coverage."""
import numpy as np
import pytest

from rayvr import Renderer
from rayvr.accel.bvh import build_bvh, trace_reference
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.frame.cameras import Distorted, Foveated, Pinhole, ThinLens, Wide
from rayvr.renderer import RenderSettings
from rayvr.scene.loader import Material, from_arrays, load

NO_HIT = 0xFFFFFFFF
ROOM_POSE = Pose.look_at([0.3, 1.5, 1.0], [0, 1.2, -1])  # inside the default room: walls everywhere
DARK = dict(ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0))


@pytest.fixture(scope="module")
def room():
    return load(None)


def edge_scene():
    """One emissive triangle (radiance 1) on black, its left edge slanted across the view of a
    camera at the origin looking down -z: frames show coverage directly."""
    return from_arrays([[-0.5, -3.0, -2.0], [0.4, 3.0, -2.0], [12.0, 0.0, -2.0]], [[0, 1, 2]],
                       materials=[Material("glow", base_color=(0.0, 0.0, 0.0, 1.0), emission=(1.0, 1.0, 1.0),
                                           double_sided=True)],  # wound away from the camera
                       triangle_material=[0], ambient_lights=False, name="edge")


def inside_edge_triangle(origins, directions) -> np.ndarray:
    """Numpy: does each ray meet the edge scene's triangle? (ray-plane z = -2, barycentric test)"""
    a, b, c = (np.array(v) for v in ([-0.5, -3.0, -2.0], [0.4, 3.0, -2.0], [12.0, 0.0, -2.0]))
    t = (-2.0 - origins[..., 2]) / directions[..., 2]
    p = origins + t[..., None] * directions
    def side(u, v):
        return (v[0] - u[0]) * (p[..., 1] - u[1]) - (v[1] - u[1]) * (p[..., 0] - u[0])
    s1, s2, s3 = side(a, b), side(b, c), side(c, a)
    return (t > 0) & (((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0)))


def numpy_ids(scene, rays):
    """Triangle IDs of `rays` by the numpy BVH traversal (rows top-down), NO_HIT where none."""
    bvh = build_bvh(scene.vertices, scene.indices)
    h, w = rays.valid.shape
    o = (rays.origins - scene.origin).reshape(-1, 3)
    hits = trace_reference(bvh, o, rays.directions.reshape(-1, 3), tmin=1e-4)
    prim = np.asarray(hits.prim if hasattr(hits, "prim") else hits[0]).reshape(h, w).astype(np.int64)
    return np.where((prim >= 0) & rays.valid, prim, NO_HIT)


# ------------------------------------------------------------- visibility per camera model

@pytest.mark.parametrize("model, fov", [(Distorted(center=(0.05, 0.0)), 90), (Wide(fov_x=210), 130),
                                        (Wide(mapping="equidistant", fov_x=200), 180),
                                        (Foveated(mar_slope=0.1), 90), (ThinLens(aperture=0.05, focus=2.0), 90)],
                         ids=["distorted", "wide210x130", "fisheye180", "foveated", "dof"])
def test_ray_cast_visibility_matches_a_numpy_trace_of_the_models_rays(gl, room, model, fov):
    """1x: one ray per sample, the model's central ray; the GPU sees what numpy's traversal of the
    numpy reference rays sees (both eyes; with a chromatic model, the kept G-buffer is green's)."""
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=fov, size=(32, 24), near=1e-3, camera=model)
    with Renderer(room, gl=gl, settings=RenderSettings(primary="rays")) as r:
        frame = r.render(rig, aux=("triangle", "hdr"))
    kept = 1 if model.channels == 3 else 0
    for eye in rig.eyes():
        got = frame[eye.name].aux["triangle"].astype(np.int64)
        ref = numpy_ids(room, model.rays(eye, kept))
        assert (ref != NO_HIT).mean() > 0.3
        assert (got == ref).mean() >= 0.995, (eye.name, (got == ref).mean())
        assert np.isfinite(frame[eye.name].aux["hdr"]).all()


def test_pinhole_rays_reproduce_the_raster_gbuffer(gl, room):
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(64, 48), near=1e-3)
    ids = {}
    for primary in ("raster", "rays"):
        with Renderer(room, gl=gl, settings=RenderSettings(primary=primary)) as r:
            ids[primary] = r.render(rig, aux=("triangle",))
    for eye in ("left", "right"):
        a, b = ids["raster"][eye].aux["triangle"], ids["rays"][eye].aux["triangle"]
        assert (a == b).mean() >= 0.995


# ------------------------------------------------------------- MSAA / SSAA for rays

def edge_frames(gl, settings_list, size=(48, 36), camera=None):
    scene = edge_scene()
    rig = StereoRig(Pose(np.zeros(3), np.eye(3)), ipd=0.0, fov_y=60, size=size, camera=camera or Pinhole())
    out = []
    with Renderer(scene, gl=gl, settings=RenderSettings(**DARK, **settings_list[0])) as r:
        for s in settings_list:
            r.settings = RenderSettings(**DARK, **s)
            out.append(r.render(rig, eyes="left", aux=("hdr", "triangle")))
    return rig.eye("left"), out


def test_msaa_coverage_at_an_analytic_edge(gl):
    eye, (one, msaa, ssaa) = edge_frames(gl, [dict(msaa=1), dict(msaa=16), dict(msaa=16, ssaa=True)])
    model = Pinhole()
    # The true coverage: 32 x 32 points per pixel, numpy.
    w, h = eye.size
    k = 32
    fx = (np.arange(w * k) + 0.5) / k
    fy = (h - (np.arange(h * k) + 0.5) / k)[:, None]
    from rayvr.frame.cameras.pinhole import planar_directions
    d = planar_directions(eye, fx[None, :], fy)
    area = inside_edge_triangle(np.zeros_like(d), d).reshape(h, k, w, k).mean(axis=(1, 3))
    # The sub-rays' own coverage: the same 16 rays, traced in numpy.
    frac = np.mean([inside_edge_triangle(r.origins, r.directions)
                    for r in (model.rays(eye, 0, (i, 16)) for i in range(16))], axis=0)
    edge = (area > 0.02) & (area < 0.98)
    assert edge.sum() > 30
    got = {name: f.left.aux["hdr"][..., 0].astype(np.float64) for name, f in (("1x", one), ("msaa", msaa), ("ssaa", ssaa))}
    # Exactly the sub-rays' fraction (float16 colour; a sub-ray exactly on the edge may go either way).
    assert (np.abs(got["msaa"] - frac) < 2e-3).mean() > 0.99
    np.testing.assert_allclose(got["ssaa"], got["msaa"], atol=2e-3)  # constant radiance: shading per sub-ray changes nothing
    # Anti-aliased: near the true area at the edge, where one ray per pixel is 0 or 1.
    err = {n: np.abs(g - area)[edge] for n, g in got.items()}
    assert err["msaa"].mean() < 0.06 and err["msaa"].max() < 0.2, (err["msaa"].mean(), err["msaa"].max())
    assert err["1x"].mean() > 3 * err["msaa"].mean()
    assert set(np.unique(got["1x"].round(3))) <= {0.0, 1.0}
    # Away from the edge every pixel is exact.
    np.testing.assert_allclose(got["msaa"][area >= 0.999], 1.0, atol=1e-3)
    np.testing.assert_allclose(got["msaa"][area <= 0.0], 0.0, atol=1e-6)


def test_msaa_1x_is_one_ray_per_pixel(gl):
    eye, (plain, one) = edge_frames(gl, [dict(primary="rays"), dict(msaa=1, primary="rays")])
    rays = Pinhole().rays(eye)
    covered = inside_edge_triangle(rays.origins, rays.directions)
    for f in (plain, one):
        hit = f.left.aux["triangle"] != NO_HIT
        assert (hit == covered).mean() > 0.99
        np.testing.assert_array_equal(f.left.aux["hdr"][..., 0] > 0.5, hit)


def test_msaa_frames_run_one_shading_round_per_distinct_triangle(gl, room):
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(32, 24), near=1e-3)
    with Renderer(room, gl=gl, settings=RenderSettings(msaa=8)) as r:
        fc = r.record(rig)
        r.gl.ctx.finish()
        rounds = fc.round.index + 1
        timings = r.read_ms(fc)
        # slot-major: slot k of every pixel, then slot k + 1
        hits = np.moveaxis(np.frombuffer(r.resource("msaa_hits").read(), np.uint32).reshape(8, 2, 24, 32, 4), 0, 3)
    counts = (hits[..., 0, 2] >> 8) & 255
    assert rounds == counts.max() >= 2  # the room's edges: several triangles in some pixels
    coverage = hits[..., 1]  # each entry's sub-rays
    covered = np.array([[[int(coverage[e, y, x, :counts[e, y, x]].sum()) for x in range(32)] for y in range(24)]
                        for e in range(2)])
    assert (covered == 8).all()  # every sub-ray of every pixel lands in one slot (8 slots for 8 rays)
    assert (covered == hits[..., 0, 2] >> 16).all()  # the pixel's count of them, in its first entry
    assert set(timings) >= {"primary_rays", "gbuffer", "shade", "sample_accumulate", "sample_resolve", "tonemap"}


@pytest.mark.parametrize("n, kept, merge", [(4, 8, "triangle"), (4, 8, "surface"), (32, 8, "triangle"),
                                            (8, 2, "triangle"), (8, 2, "surface")])
def test_msaa_lists_match_a_numpy_merge_of_numpy_traced_sub_rays(gl, room, n, kept, merge):
    """The MSAA trace (one invocation per sub-ray, merged per pixel in shared memory; a 30x22 or
    18x14 image leaves partial pixel blocks) against passes/primary_rays.msaa_lists over numpy
    traces of the model's own sub-rays: the same distinct triangles, coverages, counts and
    order; the representative sub-ray is one nearest the mean offset of the sub-rays numpy saw on
    its triangle, its distance that sub-ray's. 32 sub-rays at the smaller size: numpy traces each of
    them. With shading_slots 2 (`kept`) a pixel keeps its two most covered triangles, wherever
    their first sub-rays fall. With shading_merge "surface" an entry is a smooth surface's sub-rays
    at one depth (the mirror sphere's many triangles in a pixel make one entry): numpy merges by
    scene/surfaces.py's surfaces, and makes fewer entries than by triangle where a pixel sees the
    sphere's or torus's triangles."""
    from rayvr.frame.cameras.sampling import subsamples
    from rayvr.frame.passes.primary_rays import msaa_lists
    from rayvr.scene.surfaces import surface_groups

    (w, h), slots = (30, 22) if n < 32 else (18, 14), min(n, kept)
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(w, h), near=1e-3)
    surfaces = surface_groups(room.vertices, room.indices, room.triangle_material, room.normals) if merge == "surface" else None
    with Renderer(room, gl=gl, settings=RenderSettings(msaa=n, shading_slots=kept, shading_merge=merge)) as r:
        r.record(rig)
        r.gl.ctx.finish()
        got = np.frombuffer(r.resource("msaa_hits").read(), np.uint32).reshape(slots, 2, h, w, 4)
    bvh = build_bvh(room.vertices, room.indices)
    offsets, _ = subsamples(n)
    for e, eye in enumerate(rig.eyes()):
        tris, ts = [], []
        for i in range(n):  # numpy's traversal of sub-ray i of every pixel, GL rows (bottom-up) as the GPU's
            rays = Pinhole().rays(eye, 0, (i, n))
            prim, t, _, _ = trace_reference(bvh, (rays.origins - room.origin).reshape(-1, 3),
                                            rays.directions.reshape(-1, 3), tmin=1e-4)
            tris.append(np.asarray(prim, np.uint32).reshape(h, w)[::-1])
            ts.append(np.asarray(t, np.float32).reshape(h, w)[::-1])
        sub_tris = np.stack(tris, -1)
        ref = msaa_lists(sub_tris, np.stack(ts, -1), offsets, slots, surfaces=surfaces)
        if merge == "surface":  # the smooth objects' triangles merged: fewer entries than by triangle
            by_triangle = msaa_lists(sub_tris, np.stack(ts, -1), offsets, slots)
            fewer = (ref[0, ..., 2] >> 8) < (by_triangle[0, ..., 2] >> 8)
            assert fewer.sum() >= 3, fewer.sum()
        mine = got[:, e]
        count = (mine[0, ..., 2] >> 8) & 255
        assert count.max() >= 2 and (count >= 1).all()  # edges in view; every pixel has its list
        # Entries at and past a pixel's count are never written (nor read by the select rounds): the
        # buffer keeps whatever it held, so only each pixel's first `count` entries are compared.
        used = np.arange(slots)[:, None, None] < count[None]
        same = (((mine[..., :2] == ref[..., :2]).all(-1) | ~used).all(0)
                & (mine[0, ..., 2] >> 8 == ref[0, ..., 2] >> 8))
        assert same.mean() >= 0.97, same.mean()  # sub-rays grazing an edge may go either way
        for y, x in zip(*np.nonzero(same)):
            for k in range(count[y, x]):
                tri, _, meta, tbits = (int(v) for v in mine[k, y, x])
                if merge == "surface":  # the entry's sub-rays are the numpy merge's: its representative
                    assert meta & 255 == ref[k, y, x, 2] & 255
                    continue
                bits = [i for i in range(n) if sub_tris[y, x, i] == tri]
                dist = ((offsets[bits] - offsets[bits].mean(0)) ** 2).sum(1)
                best = meta & 255
                assert best in bits and dist[bits.index(best)] <= dist.min() + 1e-6
                if tri != NO_HIT:
                    t = np.frombuffer(np.uint32(tbits).tobytes(), np.float32)[0]
                    np.testing.assert_allclose(t, ts[best][y, x], rtol=1e-4)


def test_msaa_lists_ignore_what_the_buffer_held_before(gl, room):
    """A pixel's list entries past its count are left as the buffer had them (a recycled buffer
    holds another frame's data, or garbage on a GPU): filling the lists with garbage between two
    frames changes neither their used entries nor the frame."""
    n, w, h, slots = 4, 30, 22, 4
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(w, h), near=1e-3)
    with Renderer(room, gl=gl, settings=RenderSettings(msaa=n)) as r:
        clean = r.render(rig)
        lists = np.frombuffer(r.resource("msaa_hits").read(), np.uint32).reshape(slots, 2, h, w, 4).copy()
        hits = r.resource("msaa_hits")
        hits.write(np.full(hits.size // 4, 0xDEADBEEF, np.uint32).tobytes())
        dirty = r.render(rig)
        again = np.frombuffer(hits.read(), np.uint32).reshape(slots, 2, h, w, 4)
    count = (lists[0, ..., 2] >> 8) & 255
    used = np.arange(slots)[:, None, None, None] < count[None]
    assert count.max() >= 2 and used.any() and not used.all()  # some entries are unused
    assert ((again == lists).all(-1) | ~used).all()
    for eye in ("left", "right"):
        assert np.array_equal(getattr(clean, eye).color, getattr(dirty, eye).color)
        assert np.array_equal(getattr(clean, eye).depth, getattr(dirty, eye).depth)


@pytest.mark.parametrize("poll", ["wait", "fence"])
def test_msaa_rounds_are_counted_once_the_first_round_is_recorded(gl, room, monkeypatch, count_poll, poll):
    """The CPU reads the MSAA round count after the first round's passes are all recorded (the GPU
    works through them meanwhile), at most once per frame; the rounds are still one per distinct
    triangle once it is known. "wait": the count is there as soon as it is asked for (llvmpipe's
    timing); "fence": whenever the GPU gets there (an H200 is still on the first round when the
    CPU asks, so rounds are recorded before the count is known, up to the most a pixel may need)."""
    from rayvr.frame.passes import primary_rays
    from rayvr.frame.passes.sample_accumulate import SampleAccumulatePass

    count_poll(poll)

    events = []
    accumulate = SampleAccumulatePass.execute
    monkeypatch.setattr(SampleAccumulatePass, "execute", lambda self, fc: (events.append("accumulate"),
                                                                          accumulate(self, fc))[1])

    class LoggedReadback:  # the pass's readback buffer, its reads logged
        def __init__(self, buf):
            self.buf, self.mglo = buf, buf.mglo

        def read(self):
            events.append("read")
            return self.buf.read()

        def release(self):
            self.buf.release()

    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(32, 24), near=1e-3)
    with Renderer(room, gl=gl, settings=RenderSettings(msaa=8)) as r:
        r.record(rig)  # compiles the graph
        (prim,) = [p for g in r.graph._compiled.values() for p in g.passes if p.name == "primary_rays"]
        prim.count_io[1] = LoggedReadback(prim.count_io[1])
        events.clear()
        fc = r.record(rig)
        r.gl.ctx.finish()
        hits = np.frombuffer(r.resource("msaa_hits").read(), np.uint32).reshape(8, 2, 24, 32, 4)
    rounds, needed = fc.round.index + 1, ((hits[0, ..., 2] >> 8) & 255).max()
    assert needed >= 2  # the room's edges: several triangles in some pixels
    if poll == "wait":
        assert rounds == needed
        assert events == ["accumulate", "read"] + ["accumulate"] * (rounds - 1)
        return
    assert events[0] == "accumulate" and events.count("read") <= 1 and events.count("accumulate") == rounds
    if "read" in events:  # rounds recorded before the count was known, then as many as it says
        assert rounds == max(events.index("read"), needed)
    else:  # the GPU never answered while recording: every round a pixel may need
        assert rounds == primary_rays.msaa_slots(fc.plan)


# ------------------------------------------------------------- channels, lens, foveation

def test_chromatic_channels_are_each_cast_on_their_own_rays(gl):
    """A chromatic lens frame's red channel is the red of a frame made with the red polynomial
    alone (and so on): each channel set is cast and shaded on its own grid, then composed."""
    k = ((0.1, 0.0, 0.0), (0.3, 0.0, 0.0), (0.6, 0.0, 0.0))
    centre = (0.6, 0.3)  # off the edge: the channels' radial stretch moves it by several pixels
    _, (chromatic,) = edge_frames(gl, [dict()], camera=Distorted(coefficients=k, center=centre))
    for c in range(3):
        _, (mono,) = edge_frames(gl, [dict()], camera=Distorted(coefficients=k[c], center=centre))
        np.testing.assert_array_equal(chromatic.left.aux["hdr"][..., c], mono.left.aux["hdr"][..., c])
    reds, blues = (chromatic.left.aux["hdr"][..., c] > 0.5 for c in (0, 2))
    assert (reds != blues).sum() > 10  # the lens moves the edge differently per channel


def test_dof_with_zero_aperture_renders_the_pinhole_and_is_stereo_consistent(gl, room):
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(32, 24), near=1e-3)
    with Renderer(room, gl=gl, settings=RenderSettings(msaa=4)) as r:
        pin = r.render(rig, aux=("hdr",))
        zero = r.render(StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(32, 24), near=1e-3,
                                  camera=ThinLens(aperture=0.0)), aux=("hdr",))
        blur = r.render(StereoRig(ROOM_POSE, ipd=0.0, fov_y=90, size=(32, 24), near=1e-3,
                                  camera=ThinLens(aperture=0.1, focus=1.0)), aux=("hdr",))
    for eye in ("left", "right"):
        np.testing.assert_array_equal(zero[eye].aux["hdr"], pin[eye].aux["hdr"])
    np.testing.assert_array_equal(blur.left.aux["hdr"], blur.right.aux["hdr"])  # IPD 0: the same lens samples
    assert np.abs(blur.left.aux["hdr"].astype(float) - pin.left.aux["hdr"]).max() > 0.01


def test_foveated_frame_is_reconstructed_for_display(gl, room):
    model = Foveated(mar_slope=0.1, fovea_radius=2.0)
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(48, 36), near=1e-3, camera=model)
    full_rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(48, 36), near=1e-3)
    with Renderer(room, gl=gl, settings=RenderSettings(primary="rays")) as r:
        fov = r.render(rig, aux=("hdr", "triangle"))
        full = r.render(full_rig, aux=("hdr",))
    for eye in rig.eyes():
        sample = model.footprint(eye) > 0
        assert 0.2 < sample.mean() < 0.8
        got = fov[eye.name].aux["hdr"][..., :3].astype(np.float64)
        ref = full[eye.name].aux["hdr"][..., :3].astype(np.float64)
        np.testing.assert_array_equal(got[sample], ref[sample])  # samples: the pinhole's own pixels
        assert (fov[eye.name].aux["triangle"][~sample] == NO_HIT).all()  # between them: no ray cast
        expected = model.reconstruct(eye, np.where(sample[..., None], ref, 0.0))
        np.testing.assert_allclose(got, expected, atol=2e-3, rtol=2e-3)  # the numpy twin of the GPU fill


def test_samples_view_shows_the_pattern(gl, room):
    model = Foveated(mar_slope=0.1, fovea_radius=2.0)
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(48, 36), camera=model)
    with Renderer(room, gl=gl) as r:
        f = r.render(rig, eyes="left", view="samples")
        chroma = r.render(StereoRig(ROOM_POSE, size=(48, 36), camera=Distorted()), eyes="left", view="samples")
    lit = f.left.color.max(axis=-1) > 0
    np.testing.assert_array_equal(lit, model.footprint(rig.eye("left")) > 0)  # black between samples
    c = chroma.left.color.astype(int)
    assert (c[..., 0] != c[..., 2]).any()  # the three channel sets' grids differ
