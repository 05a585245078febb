"""Ray packets (glsl/accel/packet.glsl): several rays traced together by one invocation, sharing each
box test, must give every ray the hit that tracing it alone gives (per-ray traversal, the reference),
bit for bit; and MSAA frames traced in packets (RenderSettings.msaa_packet) equal per-sub-ray ones."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr import Renderer, shaders
from rayvr.accel.bvh import build_bvh
from rayvr.accel.gpu import MISS, GpuBvh, RayTracer, pack_rays
from rayvr.camera import Pose, StereoRig
from rayvr.cameras import Distorted, Pinhole, ThinLens, Wide
from rayvr.renderer import RenderSettings
from rayvr.scene import load

ROOM_POSE = Pose.look_at([0.3, 1.5, 1.0], [0, 1.2, -1])


def soup(n, seed=0):
    rng = np.random.default_rng(seed)
    v = (rng.uniform(-5, 5, (n, 1, 3)) + rng.normal(size=(n, 3, 3))).reshape(-1, 3).astype(np.float32)
    return v, np.arange(3 * n).reshape(n, 3)


def trace_in_packets(gl, rt: RayTracer, o, d, tmin, tmax, k: int):
    """(prim, t bits) of rays traced k to an invocation through trace_rays.comp's PACKET_RAYS path."""
    rays = pack_rays(o, d, tmin, tmax)
    n = len(rays)
    prog = shaders.compute(gl.ctx, "accel/trace_rays.comp", dict(
        rt.gpu_bvh.own_defines(rt.base, True), TRACE_MODE=0, RAYS_BINDING=rt.base + 2,
        HITS_BINDING=rt.base + 3, PACKET_RAYS=k))
    bufs = [gl.ctx.buffer(rays.tobytes()), gl.ctx.buffer(reserve=n * 16)]
    try:
        rt.gpu_bvh.bind(rt.base)
        bufs[0].bind_to_storage_buffer(rt.base + 2)
        bufs[1].bind_to_storage_buffer(rt.base + 3)
        prog["ray_count"].value = n
        prog.run(-(-n // (64 * k)), 1, 1)
        out = np.frombuffer(bufs[1].read(), np.uint32).reshape(-1, 4)
    finally:
        for b in (*bufs, prog):
            b.release()
    return out[:, 0], out[:, 1]


def bundles(v, packets, k, spread, seed):
    """`packets` groups of k rays: each group from one point (or a small lens) towards the soup, its
    directions within `spread` of each other (spread 1: unrelated directions, mixed signs)."""
    rng = np.random.default_rng(seed)
    lo, hi = v.min(0), v.max(0)
    c, r = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    o = np.repeat(c + rng.normal(size=(packets, 3)) * r, k, axis=0)
    o += rng.normal(size=o.shape) * 0.01 * r * (rng.uniform(size=(len(o), 1)) < 0.5)   # some lenses
    aim = np.repeat(c + rng.normal(size=(packets, 3)) * 0.2 * r, k, axis=0)
    d = aim - o + rng.normal(size=o.shape) * spread * r
    return o.astype(np.float32), d.astype(np.float32)


@pytest.mark.parametrize("k", [2, 4, 8])
def test_packets_return_every_rays_own_closest_hit(gl, k):
    v, f = soup(1500)
    rt = RayTracer(gl, GpuBvh(gl, build_bvh(v, f)))
    parts = [bundles(v, 300, k, s, seed) for seed, s in enumerate((0.002, 0.05, 1.0))]
    o = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    n = len(o)
    # rays that trace nothing, alone in a packet or beside live ones; axis-parallel directions
    d[5] = 0.0
    d[9, 1] = np.nan
    d[16:16 + k] = 0.0
    d[40:40 + k, 0] = 0.0
    d[41, 1] = -0.0
    tmin = np.zeros(n, np.float32)
    tmax = np.full(n, np.inf, np.float32)
    tmin[100:200] = 0.3 * np.linalg.norm(d[100:200], axis=1)   # intervals, some empty
    tmax[150:260] = np.linspace(0.0, 2.0, 110)
    m = n - 3                                                 # not a whole number of packets
    ref = rt.trace(o[:m], d[:m], tmin[:m], tmax[:m])
    prim, tbits = trace_in_packets(gl, rt, o[:m], d[:m], tmin[:m], tmax[:m], k)
    assert 0.2 < (ref.prim != MISS).mean() < 0.95
    np.testing.assert_array_equal(prim, ref.prim)
    hit = ref.prim != MISS
    np.testing.assert_array_equal(tbits[hit], ref.t[hit].astype(np.float32).view(np.uint32))


@pytest.fixture(scope="module")
def room():
    return load(None)


def test_packets_of_camera_sub_rays_in_the_room(gl, room):
    """Sub-ray packets of a camera's pixels (one origin, directions a pixel apart), among them pixels
    whose sub-rays go both ways along a scene axis: the room's wall at the end of such a packet was
    lost before those packets were traced one ray at a time."""
    from rayvr.accel.scene import build_scene_bvh
    from rayvr.bench.rays import primary_rays
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=90, size=(80, 60), near=1e-3)
    o, d = primary_rays(rig, room.origin)
    k = 4
    rng = np.random.default_rng(1)
    o = np.repeat(o, k, axis=0)
    d = np.repeat(d, k, axis=0) + rng.normal(size=(len(o), 3)).astype(np.float32) * 0.004
    rt = RayTracer(gl, GpuBvh(gl, build_scene_bvh(room, progress=False)))
    ref = rt.trace(o, d, 1e-3, np.inf)
    prim, tbits = trace_in_packets(gl, rt, o, d, 1e-3, np.inf, k)
    np.testing.assert_array_equal(prim, ref.prim)
    hit = ref.prim != MISS
    assert hit.mean() > 0.9
    np.testing.assert_array_equal(tbits[hit], ref.t[hit].astype(np.float32).view(np.uint32))


@pytest.mark.parametrize("camera,fov,msaa", [(Pinhole(), 90, 4), (Pinhole(), 90, 16),
                                             (ThinLens(aperture=0.05, focus=1.5), 90, 8),
                                             (Wide(fov_x=210.0), 130, 4),   # rays of all signs in one packet
                                             (Distorted(), 90, 4)])         # chromatic: a channel set a round
def test_msaa_packets_render_the_frame_of_single_sub_rays(gl, room, camera, fov, msaa):
    rig = StereoRig(ROOM_POSE, ipd=0.064, fov_y=fov, size=(40, 30), near=1e-3, camera=camera)
    frames = []
    for packet in (1, 4):
        with Renderer(room, gl=gl, settings=RenderSettings(msaa=msaa, msaa_packet=packet)) as r:
            frames.append(r.render(rig, aux=("hdr", "depth")))
    one, four = frames
    for eye in ("left", "right"):
        assert one[eye].aux["hdr"].std() > 0
        np.testing.assert_array_equal(four[eye].aux["hdr"], one[eye].aux["hdr"])
        np.testing.assert_array_equal(four[eye].aux["depth"], one[eye].aux["depth"])


def test_msaa_packet_is_checked(gl):
    with pytest.raises(ValueError, match="msaa_packet"):
        RenderSettings(msaa_packet=3)
