import os
import re
import subprocess
import sys

import numpy as np
import pytest

from rayvr.gl.context import ContextError, create_context


def test_context_is_4_3_core_with_what_rayvr_needs(gl):
    info = gl.info()
    assert info["version_code"] >= 430
    assert info["limits"]["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"] >= 2 ** 24
    assert set(info["extensions"]) >= {"GL_ARB_shader_viewport_layer_array", "GL_OVR_multiview"}
    assert gl.raw.has("glFramebufferTexture")


def test_info_reads_the_glsl_version_and_every_limit_from_the_driver(gl):
    # moderngl's ctx.info has no GLSL version nor compute shared memory size: both printed None.
    info = gl.info()
    major, minor = (int(p) for p in info["glsl"].split()[0].split(".")[:2])
    assert (major, minor) >= (4, 30)
    assert all(isinstance(v, int) and v > 0 for v in info["limits"].values()), info["limits"]
    assert info["limits"]["GL_MAX_COMPUTE_SHARED_MEMORY_SIZE"] >= 32768  # the GL 4.3 minimum


def test_unknown_backend_lists_what_was_tried():
    with pytest.raises(ContextError) as e:
        create_context("vulkan")
    assert "unknown backend 'vulkan'" in str(e.value) and "egl, osmesa" in str(e.value)


def _capture(backend, out):
    env = {**os.environ, "RAYVR_GL_BACKEND": backend}
    cmd = [sys.executable, "-m", "rayvr", "capture", "--size", "48x32", "--out", str(out), "-q",
           "--aux", "triangle"]
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)


def test_egl_and_osmesa_render_the_same_frame(tmp_path):
    """Each backend in its own process (one GL context per process), same default scene."""
    from PIL import Image

    results = {}
    for backend in ("egl", "osmesa"):
        run = _capture(backend, tmp_path / backend)
        if run.returncode != 0 and "no OpenGL 4.3 core context" in run.stderr:
            pytest.skip(f"{backend} unavailable: {run.stderr.strip()}")
        assert run.returncode == 0, run.stderr
        results[backend] = (np.asarray(Image.open(tmp_path / backend / "frame_left.png")),
                            np.load(tmp_path / backend / "frame_left_triangle.npy"))
    (ce, te), (co, to) = results["egl"], results["osmesa"]
    assert (te == to).mean() > 0.999
    assert np.abs(ce.astype(int) - co).max() <= 2


def test_no_context_error_is_clear():
    """With every backend broken the error names each one and why."""
    env = {**os.environ, "GLCONTEXT_LINUX_LIBEGL": "/nonexistent/libEGL.so", "LD_LIBRARY_PATH": "/nonexistent"}
    code = ("import ctypes.util, rayvr.gl.context as c\n"
            "ctypes.util.find_library = lambda name: '/nonexistent/lib' + name + '.so'\n"
            "try:\n    c.create_context()\nexcept c.ContextError as e:\n    print(e)\n")
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert "no OpenGL 4.3 core context could be made" in run.stdout, run.stdout + run.stderr
    assert "- egl:" in run.stdout and "- osmesa:" in run.stdout


def test_gbuffer_suite_passes_under_osmesa():
    """The analytic G-buffer tests again, in a child process on the OSMesa backend."""
    from pathlib import Path

    here = Path(__file__).parent
    probe = subprocess.run([sys.executable, "-c", "import rayvr.gl.context as c; c.create_context('osmesa')"],
                           capture_output=True, text=True, timeout=120)
    if probe.returncode != 0:
        pytest.skip(f"OSMesa unavailable: {probe.stderr.strip().splitlines()[-1:]}")
    env = {**os.environ, "RAYVR_GL_BACKEND": "osmesa"}
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(here / "test_gbuffer.py")],
                         env=env, capture_output=True, text=True, timeout=600, cwd=here.parent)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert " passed" in run.stdout and "skipped" not in run.stdout.splitlines()[-1]


def test_a_gl_error_during_a_frame_is_an_error_not_an_image(gl):
    """A failed GL call while a frame is drawn (here an out-of-range buffer binding made from a
    pass, as an exhausted device or a too-large dispatch would) raises GpuError naming the
    error; a clean frame raises nothing, and errors left from before the frame do not count."""
    from rayvr.scene import loader as scene_mod
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.gl.context import GpuError
    from rayvr.renderer import Renderer

    scene = scene_mod.load(None)
    rig = StereoRig.for_scene(scene, size=(16, 12))
    with Renderer(scene, gl=gl) as r:
        r.render(rig)  # clean
        gl.raw.glBindBuffer(0xDEAD, 0)  # GL_INVALID_ENUM before the frame: not the frame's
        r.render(rig)
        tonemap = next(p for p in r.graph.compile(r.plan(2, "color", rig.eyes()[0].camera)).passes if p.name == "tonemap")
        original = tonemap.execute

        def failing(fc):
            original(fc)
            gl.raw.glBindBuffer(0xDEAD, 0)
        tonemap.execute = failing
        with pytest.raises(GpuError, match="GL_INVALID_ENUM") as failed:
            r.render(rig)
        tonemap.execute = original
        if gl._logging:  # the suite turns the driver's log on (RAYVR_GL_DEBUG): its words follow
            said = re.search(r"GL_INVALID_ENUM \(.*?\): (.+); the image would be wrong$", str(failed.value))
            assert said and len(said.group(1)) > 8, str(failed.value)
        assert np.asarray(r.render(rig).left.color).any()  # the next frame is fine again


def test_a_released_renderer_leaves_no_dead_framebuffer_bound(gl):
    """Renderers come and go on one context (benchmarks, tests): after one is released, the
    next one's frames (with accumulation, whose readback made moderngl rebind its current
    framebuffer by name) report no GL error, and moderngl's current framebuffer is alive."""
    from rayvr.scene import loader as scene_mod
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import Renderer

    scene = scene_mod.load(None)
    rig = StereoRig.for_scene(scene, size=(16, 12))
    with Renderer(scene, gl=gl) as first:
        first.render(rig, spp=2)
    gl.gl_errors()
    with Renderer(scene, gl=gl) as second:
        for spp in (1, 2, 3):
            second.render(rig, spp=spp)  # GpuError if a frame's GL calls failed
    assert gl.gl_errors() == []


def test_a_second_context_made_or_released_in_the_process_leaves_the_first_one_working(gl):
    """GL calls go to the thread's current context. A second context (a benchmark's own, a
    Renderer made without gl=) took them over, and kept them after its release: the first
    context's next frame failed on every name (glBindFramebuffer(non-gen name)). Renderers on
    two live contexts in turn, and on the first after the second is released, draw the same frame."""
    from rayvr.scene import loader as scene_mod
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import Renderer

    scene = scene_mod.load(None)
    rig = StereoRig.for_scene(scene, size=(16, 12))
    with Renderer(scene, gl=gl) as r:
        before = r.render(rig).left.color
    other = create_context()
    try:
        with Renderer(scene, gl=gl) as here, Renderer(scene, gl=other) as there:
            for _ in range(2):  # in turn: each frame on its own context
                np.testing.assert_array_equal(here.render(rig).left.color, before)
                np.testing.assert_array_equal(there.render(rig).left.color, before)
    finally:
        other.release()
    with Renderer(scene, gl=gl) as r:  # the released one was current: the first is again
        np.testing.assert_array_equal(r.render(rig).left.color, before)
    bench_own = create_context()  # made and released around no Renderer of its own
    bench_own.release()
    with Renderer(scene, gl=gl) as r:
        np.testing.assert_array_equal(r.render(rig).left.color, before)
    assert gl.gl_errors() == []


def test_a_fence_wait_returns_once_the_gpu_has_run_the_work_before_it(gl):
    """GLContext.fence: after wait() a compute shader's writes recorded before the fence are
    there (read without any other synchronising call), and the sync object is deleted."""
    shader = gl.ctx.compute_shader("""#version 430
        layout(local_size_x = 64) in;
        layout(std430, binding = 0) buffer Out { uint v[]; };
        void main() { uint i = gl_GlobalInvocationID.x; uint x = i; for (int k = 0; k < 64; ++k) x = x * 1664525u + 1013904223u; v[i] = x; }""")
    n = 1 << 14
    buf = gl.ctx.buffer(reserve=4 * n)
    buf.bind_to_storage_buffer(0)
    shader.run(n // 64)
    fence = gl.fence()
    fence.wait()
    assert fence.sync is None
    expected = np.arange(n, dtype=np.uint64)
    for _ in range(64):
        expected = (expected * 1664525 + 1013904223) % (1 << 32)
    assert np.array_equal(np.frombuffer(buf.read(), np.uint32), expected.astype(np.uint32))
    fence.release()  # a second release is harmless
    buf.release()
    shader.release()


def test_an_accumulation_keeps_at_most_two_samples_queued_on_the_gpu(gl, monkeypatch):
    """render(spp=N) waits for sample k - SAMPLES_IN_FLIGHT before recording more: on the H200 a
    fresh Renderer that queued ~20 s of samples unsynchronised read back the previous Renderer's
    image with 0 ms timings and no GL error. Here: no more than SAMPLES_IN_FLIGHT fences are
    outstanding when a sample is recorded, and every fence is waited for or released."""
    from rayvr.scene import loader as scene_mod
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.gl.context import GLContext
    from rayvr.renderer import SAMPLES_IN_FLIGHT, Renderer

    made, open_at_record = [], []
    real_fence = GLContext.fence

    def counting_fence(self):
        f = real_fence(self)
        made.append(f)
        return f
    monkeypatch.setattr(GLContext, "fence", counting_fence)
    scene = scene_mod.load(None)
    rig = StereoRig.for_scene(scene, size=(16, 12))
    with Renderer(scene, gl=gl) as r:
        real_record = r.record

        def record(*a, **k):
            open_at_record.append(sum(f.sync is not None for f in made))
            return real_record(*a, **k)
        r.record = record
        r.render(rig, spp=7)
    assert len(open_at_record) == 7 and max(open_at_record) == SAMPLES_IN_FLIGHT
    # six between the samples, one behind the frame's read-back (frame/readback.py); all released
    assert len(made) == 7 and all(f.sync is None for f in made)


def test_a_frame_whose_passes_all_read_0_ns_on_a_gpu_is_an_error(gl, monkeypatch):
    """The H200 once returned an earlier Renderer's image for a frame whose passes all timed 0 ns
    (its commands never ran) with no GL error: on a hardware GPU such a frame raises GpuError.
    A pass that records nothing (the bvh pass once built) may read 0 alone; llvmpipe, whose
    timers can read 0 for short passes, is not checked."""
    from rayvr.scene import loader as scene_mod
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.gl.context import GLContext, GpuError
    from rayvr.renderer import Renderer, work_dropped

    assert work_dropped({"bvh": 0.001, "visibility": 0.0, "shade": 0.0, "tonemap": 0.0})
    assert not work_dropped({"bvh": 0.0, "visibility": 2.2, "shade": 0.05, "tonemap": 0.05})
    assert not work_dropped({"tonemap": 0.0})  # one pass says too little
    scene = scene_mod.load(None)
    rig = StereoRig.for_scene(scene, size=(16, 12))
    with Renderer(scene, gl=gl) as r:
        r.render(rig)
        monkeypatch.setattr(GLContext, "is_software", property(lambda self: False))
        real = r.graph.read_ms
        monkeypatch.setattr(r.graph, "read_ms", lambda fc: {k: 0.0 for k in real(fc)})
        with pytest.raises(GpuError, match="0 ns"):
            r.render(rig)
        monkeypatch.setattr(r.graph, "read_ms", lambda fc: {k: max(v, 1e-3) for k, v in real(fc).items()})
        assert np.asarray(r.render(rig).left.color).any()


def test_device_picks_the_egl_device_by_index_and_refuses_one_that_is_not_there(tmp_path):
    """--device N (RAYVR_EGL_DEVICE) renders on EGL device N, which `rayvr info` lists; a device
    that does not exist is one line naming the devices there are, with no fallback to OSMesa; it
    does not go with Ray workers, which each take the GPU Ray gives them (issue 46 item 5)."""
    from conftest import run_rayvr
    from rayvr.gl.context import egl_devices

    devices = egl_devices()
    info = run_rayvr("info")
    assert info.returncode == 0 and "EGL devices (--device N)" in info.stdout
    for d in devices:
        assert f"  {d.describe()}" in info.stdout
    last = len(devices) - 1
    ok = run_rayvr("capture", "--device", last, "--size", "16x12", "--out", tmp_path / "a", "-q")
    assert ok.returncode == 0, ok.stderr
    missing = run_rayvr("capture", "--device", len(devices), "--size", "16x12", "--out", tmp_path / "b", "-q")
    assert missing.returncode == 2 and len(missing.stderr.strip().splitlines()) == 1, missing.stderr
    assert f"--device {len(devices)}: there is no EGL device {len(devices)}" in missing.stderr
    assert "0: " in missing.stderr and "osmesa" not in missing.stderr.lower()
    assert not (tmp_path / "b").exists() or not any((tmp_path / "b").iterdir())
    workers = run_rayvr("capture", "--device", 0, "--workers", 2, "--out", tmp_path / "c")
    assert workers.returncode == 2 and "leave out --device" in workers.stderr
