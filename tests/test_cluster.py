"""Captures over Ray workers (rayvr/app/cluster.py): the EGL device each GPU worker takes, the
dispatch with retries, and on a local Ray with 2 CPU workers: byte-identical frames, a worker
killed mid-run, resuming, and the missing extra."""
import importlib.util
import json
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import quick_bench, run_rayvr
from rayvr.frame.cameras.rig import orbit, save_path
from rayvr.cli import main
from rayvr.gl.context import ContextError, EglDevice, assigned_egl_device, egl_device_for_gpu
from rayvr.util.output import OutputError

NV = "EGL_NV_device_cuda EGL_EXT_device_drm"
SOFTWARE = EglDevice(0, "EGL_MESA_device_software", None)


# ------------------------------------------------------------------ which EGL device is the worker's GPU

def test_egl_device_of_a_cuda_ordinal_when_the_driver_reports_physical_ordinals():
    # EGL lists the software device first and the GPUs in another order than CUDA.
    devices = [SOFTWARE, EglDevice(1, NV, 1), EglDevice(2, NV, 0)]
    assert egl_device_for_gpu(devices, "0", ["0"]) == 2
    assert egl_device_for_gpu(devices, "1", ["1"]) == 1
    assert assigned_egl_device({"CUDA_VISIBLE_DEVICES": "1"}, devices) == 1
    assert assigned_egl_device({"CUDA_VISIBLE_DEVICES": "0,1"}, devices) == 2  # the first visible one


def test_egl_device_when_the_driver_applies_cuda_visible_devices():
    # Ray gave this worker physical GPU 1: the driver numbers the visible GPUs from 0 and hides the rest.
    devices = [SOFTWARE, EglDevice(1, NV, None), EglDevice(2, NV, 0)]
    assert egl_device_for_gpu(devices, "1", ["1"]) == 2


def test_egl_device_without_nvidia_is_the_default_and_overrides_win():
    assert egl_device_for_gpu([SOFTWARE], "0", ["0"]) is None  # llvmpipe: the driver's default
    assert assigned_egl_device({}, [SOFTWARE]) is None
    assert assigned_egl_device({"CUDA_VISIBLE_DEVICES": ""}, [SOFTWARE]) is None  # Ray's CPU-only workers
    assert assigned_egl_device({"RAYVR_EGL_DEVICE": "3", "CUDA_VISIBLE_DEVICES": "0"}, []) == 3
    with pytest.raises(ContextError, match="RAYVR_EGL_DEVICE must be"):
        assigned_egl_device({"RAYVR_EGL_DEVICE": "gpu0"}, [])


def test_egl_device_that_cannot_be_found_is_a_clear_error():
    devices = [EglDevice(0, NV, 0), EglDevice(1, NV, 1)]
    with pytest.raises(ContextError, match="no EGL device is CUDA device 5.*EGL 0 = CUDA 0"):
        egl_device_for_gpu(devices, "5", ["5"])
    with pytest.raises(ContextError, match="not a CUDA ordinal.*RAYVR_EGL_DEVICE"):
        egl_device_for_gpu(devices, "GPU-3f2a", ["GPU-3f2a"])


def test_this_machines_egl_devices_enumerate():
    from rayvr.gl.context import egl_devices

    try:
        devices = egl_devices()
    except ContextError as exc:
        pytest.skip(f"no EGL device enumeration here: {exc}")
    assert [d.index for d in devices] == list(range(len(devices)))


# ------------------------------------------------------------------ the dispatch loop, with a fake Ray

class FakeRay:
    """ray.wait/ray.get over results computed at submit time; a task of a 'dead' worker raises."""

    class exceptions:
        class RayTaskError(Exception):
            pass

        class RayActorError(Exception):
            pass

    def wait(self, refs, num_returns=1):
        return refs[:1], refs[1:]

    def get(self, ref):
        kind, value = ref.outcome
        if kind == "died":
            raise FakeRay.exceptions.RayActorError("worker died")
        return value


class Ref:
    def __init__(self, outcome):
        self.outcome = outcome


class FakeActor:
    """A worker whose `info` ping answers at once (Ray has restarted it)."""

    def __init__(self, k):
        self.k = k
        self.info = self

    def remote(self):
        return Ref(("ok", {}))

    def __eq__(self, other):
        return other == self.k


def fake_cluster(workers):
    from rayvr.app.cluster import Cluster

    c = Cluster.__new__(Cluster)
    c.ray, c.actors, c.started = FakeRay(), [FakeActor(k) for k in range(workers)], False
    c.dead_errors, c.unavailable = (FakeRay.exceptions.RayActorError,), ()
    return c


def test_a_dead_workers_task_is_retried_with_only_its_unfinished_frames():
    calls = []

    def submit(actor, chunk):
        calls.append((actor, chunk))
        if actor == 0 and len(calls) == 1:
            return Ref(("died", None))  # worker 0 dies on its first chunk after finishing frame 0
        return Ref(("ok", chunk))

    finished = {0}
    results, retried, failed = fake_cluster(2).run([[0, 1, 2], [3, 4]], submit, size=len,
                                                   retry=lambda c: [i for i in c if i not in finished] or None)
    assert failed == [] and retried == 2  # frames 1 and 2 ran again, frame 0 did not
    assert results == {0: [1, 2], 1: [3, 4]}
    assert (0, [0, 1, 2]) in calls and [c for a, c in calls].count([1, 2]) == 1


def test_a_task_that_kills_every_worker_fails_after_max_attempts():
    from rayvr.app.cluster import MAX_ATTEMPTS

    results, retried, failed = fake_cluster(2).run([[0], [1]], lambda a, c: Ref(("died", None)) if c == [1] else
                                                   Ref(("ok", c)), size=len)
    assert results == {0: [0]} and failed == [1] and retried == MAX_ATTEMPTS - 1


class FakeRayCluster(FakeRay):
    """A running Ray of 4 CPUs whose free CPUs read `free` in turn (the last one from then on):
    actors killed just before free theirs a moment later."""

    def __init__(self, free):
        self.free = list(free)

    def is_initialized(self):
        return True

    def cluster_resources(self):
        return {"CPU": 4.0}

    def available_resources(self):
        return {"CPU": float(self.free.pop(0) if len(self.free) > 1 else self.free[0])}

    def remote(self, what):  # ray.remote(RenderWorker) is the actor class; its .remote(spec) an actor
        return self if isinstance(what, type) else object()

    def options(self, **kw):
        return self

    def kill(self, actor):
        pass


def test_workers_wait_for_the_cpus_that_workers_closed_just_before_still_hold(monkeypatch):
    from rayvr.app import cluster
    from rayvr.app.cluster import Cluster, WorkerSpec

    ray = FakeRayCluster([1, 1, 1, 2])
    monkeypatch.setattr(cluster, "require_ray", lambda: ray)
    with Cluster(2, WorkerSpec()) as c:
        assert len(c.actors) == 2 and ray.free == [2]


def test_workers_that_do_not_fit_once_the_wait_is_over_are_one_clear_error(monkeypatch):
    from rayvr.app import cluster
    from rayvr.app.cluster import Cluster, ClusterError, WorkerSpec

    monkeypatch.setattr(cluster, "require_ray", lambda: FakeRayCluster([1]))
    monkeypatch.setattr(cluster, "RESOURCE_WAIT_S", 0.3)
    start = time.monotonic()
    with pytest.raises(ClusterError, match=r"^--workers 2 needs 2 CPUs; the Ray cluster has 1 free of 4 \(and no GPU\)$"):
        Cluster(2, WorkerSpec())
    assert 0.3 <= time.monotonic() - start < 5


# ------------------------------------------------------------------ without the extra

def test_workers_without_ray_is_one_line_naming_the_extra(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    code = main(["capture", "--workers", "2", "--frames", "4", "--size", "8x8", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "rayvr[cluster]" in err and "--workers needs Ray" in err
    assert not (tmp_path / "o").exists()  # refused before any work


# ------------------------------------------------------------------ resuming (one process, no Ray)

SIZE = (24, 16)


def path_job(gl, out, poses, **kw):
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.app.capture import CaptureJob
    from rayvr.scene.loader import load

    rig = StereoRig.for_scene(load(None), size=SIZE, ipd=0.064)  # what `rayvr capture --path` builds
    return CaptureJob(rig, poses, out_dir=out, **kw)


def frames_on_disk(out):
    return {p.name: p.read_bytes() for p in sorted(out.glob("frame_*.png"))}


def test_a_rerun_renders_only_the_frames_not_complete_on_disk(gl, tmp_path):
    from rayvr.app.capture import job_identity, run_capture
    from rayvr.renderer import Renderer

    poses = orbit([0, 1, -1], 3.0, 0.5, 4)
    job = path_job(gl, tmp_path, poses)
    identity = job_identity(job, scene=None)
    with Renderer(gl=gl) as r:
        first = run_capture(r, job, progress=False, identity=identity)
        before = frames_on_disk(tmp_path)
        (tmp_path / "frame_0002_left.png").unlink()  # one eye lost: frame 2 is incomplete
        again = run_capture(r, job, progress=False, identity=identity)
        assert (first["written"], first["skipped"], again["written"], again["skipped"]) == (4, 0, 1, 3)
        assert [f.rsplit("/", 1)[-1] for f in again["files"]] == ["frame_0002_left.png", "frame_0002_right.png"]
        assert frames_on_disk(tmp_path) == before
        other = path_job(gl, tmp_path, poses, aux=("depth",))  # another job in the same folder mixes nothing in
        with pytest.raises(OutputError, match=r"holds frames of another job \(.*aux \[\] -> \[\"depth\"\]"):
            run_capture(r, other, progress=False, identity=job_identity(other, scene=None))
        changed = job_identity(job, scene={"path": "elsewhere.glb"})
        with pytest.raises(OutputError, match=r"another job \(.*scene null -> \{\"path\""):
            run_capture(r, job, progress=False, identity=changed)
        assert frames_on_disk(tmp_path) == before


# ------------------------------------------------------------------ on a local Ray with 2 CPU workers

@pytest.fixture(scope="module")
def local_ray():
    ray = pytest.importorskip("ray", reason="Ray is the cluster extra: pip install 'rayvr[cluster]'")
    import logging

    from conftest import REPO

    # Workers are new processes: they import this checkout's rayvr.
    os.environ["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    # 2 CPU workers for the module's cluster and 2 for `bench workers`, which joins this Ray.
    for attempt in (1, 2):  # Ray gives its raylet 30 s to come up: a busy 2-core machine can miss that once
        try:
            ray.init(num_cpus=4, include_dashboard=False, logging_level=logging.ERROR, log_to_driver=False)
            break
        except Exception as exc:
            ray.shutdown()
            if attempt == 2 or "timed out during startup" not in str(exc):
                raise
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def reference(gl, tmp_path_factory):
    """A 16-frame path file and its single-process capture."""
    from rayvr.app.capture import run_capture
    from rayvr.renderer import Renderer

    root = tmp_path_factory.mktemp("cluster")
    poses = orbit([0, 1, -1], 3.0, 0.5, 16)
    save_path(root / "path.json", poses)
    with Renderer(gl=gl) as r:
        run_capture(r, path_job(gl, root / "single", poses), progress=False)
    return root, poses, frames_on_disk(root / "single")


def test_workers_give_the_same_bytes_as_one_process(gl, local_ray, reference, capsys):
    """The workers write through the capture's pipeline: its writer threads and PNG level are
    theirs too, byte for byte what one process writing each frame in turn writes at that level."""
    from rayvr.app.capture import run_capture
    from rayvr.renderer import Renderer

    root, poses, single = reference
    assert len(single) == 32
    with Renderer(gl=gl) as r:
        run_capture(r, path_job(gl, root / "serial9", poses, png_compression=9, writers=1), progress=False)
    serial = frames_on_disk(root / "serial9")
    assert serial != single  # level 9 is not the default's bytes: the workers must have been told
    out = root / "workers"
    w, h = SIZE
    # the reference's config: the CLI would give the built-in room its own (default_room.toml)
    assert main(["capture", "--path", str(root / "path.json"), "--size", f"{w}x{h}", "--out", str(out),
                 "--materials", "raster.toml", "--workers", "2", "--chunk", "3", "--png-compression", "9",
                 "--writers", "3"]) == 0
    assert "frames: 16 written, 0 skipped, 0 retried, 0 failed" in capsys.readouterr().out
    assert frames_on_disk(out) == serial  # byte for byte, every frame, both eyes
    summary = json.loads((out / "frame_timings.json").read_text())
    assert summary["workers"] == 2 and summary["missing_frames"] == [] and len(summary["gpu_ms_per_frame"]) == 16
    pipeline = summary["pipeline"]
    assert (pipeline["writers"], pipeline["png_compression"], pipeline["frames"]) == (3, 9, 16)


@pytest.fixture(scope="module")
def cluster(local_ray):
    from rayvr.app.cluster import Cluster, WorkerSpec

    with Cluster(2, WorkerSpec()) as c:  # the built-in room; sweeps load benchmark scenes by name
        assert len({w["pid"] for w in c.ready()}) == 2
        yield c


def test_a_worker_killed_mid_run_still_gives_every_frame_and_a_rerun_skips_them(gl, cluster, reference):
    from rayvr.app.capture import job_identity
    from rayvr.app.cluster import run_capture_distributed

    root, poses, single = reference
    out, crash = root / "killed", root / "crashed"
    job = path_job(gl, out, poses)
    identity = job_identity(job, scene=None)
    # The first worker to finish a frame dies (os._exit) with its chunk half done.
    summary = run_capture_distributed(cluster, job, identity, progress=False, chunk=4, crash_file=str(crash))
    assert crash.exists() and summary["failed"] == 0 and summary["missing_frames"] == []
    # Each task the dead worker held goes again: the rest of the chunk it was rendering (not the
    # frame it had written) and the chunk queued behind it.
    assert 3 <= summary["retried"] <= 7
    assert frames_on_disk(out) == single
    again = run_capture_distributed(cluster, job, identity, progress=False)
    assert (again["written"], again["skipped"], again["failed"]) == (0, 16, 0)


def test_workers_resume_only_the_frames_they_verify_and_the_folder_is_held(gl, cluster, reference):
    from rayvr.app.capture import JobFolder, job_identity
    from rayvr.app.cluster import run_capture_distributed

    root, poses, single = reference
    out = root / "resumed"
    job = path_job(gl, out, poses)
    identity = job_identity(job, scene=None)
    run_capture_distributed(cluster, job, identity, progress=False)  # the workers write each frame's record
    (out / "frame_0005_left.png").write_bytes(b"\x89PNG\r\n\x1a\n")  # cut short
    with JobFolder(job, identity):  # another capture holds the folder
        with pytest.raises(OutputError, match=f"{out}: output folder is busy"):
            run_capture_distributed(cluster, job, identity, progress=False)
    again = run_capture_distributed(cluster, job, identity, progress=False)
    assert (again["written"], again["skipped"], again["failed"]) == (1, 15, 0)
    assert frames_on_disk(out) == single
    with pytest.raises(OutputError, match="holds frames of another job"):
        run_capture_distributed(cluster, job, job_identity(job, scene={"path": "elsewhere.glb"}), progress=False)


def test_sweep_variants_measured_on_workers_match_this_process(gl, cluster):
    from rayvr.bench.scenes import bench_scenes, load_bench_scene
    from rayvr.bench.tradeoff import run_sweep, variants
    from rayvr.app.cluster import sweep_measurer
    from rayvr.quality.measure import RendererPool, Variant, local_measurer
    from rayvr.scene.materials import load_config

    (name, scene, rig), = bench_scenes(["default"], (16, 12), {})
    chosen = variants(scene, load_config(None), quick=True)[:3]
    remote = sweep_measurer(cluster, load_bench_scene, name, rig, repeat=1)
    with RendererPool(gl) as pool:
        here = list(local_measurer(gl, scene, rig, 1, pool)(chosen))
        there = list(remote(chosen))
        for a, b in zip(here, there):
            assert np.array_equal(a.image, b.image) and np.array_equal(a.material, b.material)
        assert len({m.image.tobytes() for m in here}) > 1  # the variants differ
        rows, _ = run_sweep(gl, scene, rig, Variant("reference", "reference", load_config(None)), chosen, 13.3,
                            repeat=1, progress=False, with_flip=False, pool=pool, measure_all=remote)
    floor, *rows = rows  # first the noise floor, measured here (the reference drawn with another seed)
    assert floor["knob"] == "noise floor"
    assert [r["label"] for r in rows] == [v.label for v in chosen] and all(r["psnr"] > 0 for r in rows)


def test_bench_workers_quick_writes_its_result(local_ray, tmp_path):
    address = local_ray.get_runtime_context().gcs_address  # the test's Ray: no second one to start
    result = quick_bench("workers", tmp_path, "--workers", "1,2", "--address", address)
    rows = {(r["mode"], r["workers"]): r for r in result["rows"]}
    assert set(rows) == {("single process", 0), ("ray workers", 1), ("ray workers", 2)}
    assert all(r["fps"] > 0 and r["failed"] == 0 for k, r in rows.items() if k[1])
    assert rows[("ray workers", 2)]["scaling_vs_1_worker"] > 0 and len(rows[("ray workers", 2)]["devices"]) == 2
    assert [p.name for p in tmp_path.iterdir() if p.is_dir()] == []  # the frames it wrote are gone



# ------------------------------------------------------------------ an unreachable cluster (loopback only)

needs_ray = pytest.mark.skipif(importlib.util.find_spec("ray") is None,
                               reason="Ray is the cluster extra: pip install 'rayvr[cluster]'")


def _free_loopback_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def silent_listener():
    """A loopback port that accepts connections and never answers (no Ray there)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(120)
    yield server
    server.close()


def _capture_on(address, out, timeout_s):
    """The arguments of `rayvr capture` on 1 worker of the cluster at `address`."""
    return ["capture", "--workers", "1", "--address", address, "--size", "8x8", "--out", str(out),
            "--connect-timeout", str(timeout_s)]


@needs_ray
def test_an_address_where_nothing_listens_fails_at_once_in_one_line(tmp_path):
    address = f"127.0.0.1:{_free_loopback_port()}"
    start = time.monotonic()
    run = run_rayvr(*_capture_on(address, tmp_path / "out", 5), timeout=120)
    lines = run.stderr.splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert lines[0].startswith(f"rayvr capture: error: cannot reach Ray at {address}: ") and \
        "refused" in lines[0], lines[0]
    assert time.monotonic() - start < 30  # Ray's own retries took minutes
    assert not (tmp_path / "out").exists()


@needs_ray
def test_a_cluster_that_never_answers_fails_after_connect_timeout_without_rays_warnings(tmp_path, silent_listener,
                                                                                         monkeypatch):
    address = f"127.0.0.1:{silent_listener.getsockname()[1]}"
    # Ray's C++ client logs a failed attempt after this many seconds (default 5): inside the test's 3
    monkeypatch.setenv("RAY_gcs_rpc_server_connect_timeout_s", "1")
    start = time.monotonic()
    run = run_rayvr(*_capture_on(address, tmp_path / "out", 3), timeout=120)
    took = time.monotonic() - start
    assert run.stderr.splitlines() == [f"rayvr capture: error: no Ray cluster answered at {address} within 3 s "
                                       f"(--connect-timeout)"], run.stderr[-2000:]
    assert run.returncode == 2 and 3 <= took < 30, (run.returncode, took)
    assert not (tmp_path / "out").exists()


def test_a_connect_given_up_while_ray_init_runs_is_remembered_for_the_exit(silent_listener, monkeypatch):
    """The process ends with os._exit after such a connect (cli.main): Ray's exit handler could
    wait on the thread left in ray.init for ever."""
    import threading

    from rayvr.app import cluster
    from rayvr.app.cluster import ClusterError, _connect, connect_left_behind

    monkeypatch.setattr(cluster, "_left_behind", threading.Event())
    released = threading.Event()

    class HangingRay:
        def init(self, **kw):
            released.wait(30)

    address = f"127.0.0.1:{silent_listener.getsockname()[1]}"
    assert not connect_left_behind()
    try:
        with pytest.raises(ClusterError, match="no Ray cluster answered .* within 0.2 s"):
            _connect(HangingRay(), address, 0.2)
        assert connect_left_behind()
    finally:
        released.set()


@needs_ray
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_end_a_wait_for_the_cluster_at_once(tmp_path, silent_listener, sig):
    address = f"127.0.0.1:{silent_listener.getsockname()[1]}"
    proc = subprocess.Popen([sys.executable, "-m", "rayvr", *_capture_on(address, tmp_path / "out", 300)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"})  # SIGABRT: every thread's stack
    try:
        silent_listener.accept()[0].close()  # rayvr's reachability check: Ray connects next
        time.sleep(1.0)
        start = time.monotonic()
        proc.send_signal(sig)
        try:
            _, stderr = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:  # where it waits, for the record (it hung in some suite runs)
            proc.send_signal(signal.SIGABRT)
            pytest.fail(f"no exit 20 s after the signal; its threads:\n{proc.communicate(timeout=20)[1][-6000:]}")
        took = time.monotonic() - start
    finally:
        proc.kill()
    assert took < 5, took
    said = "interrupted" if sig == signal.SIGINT else "terminated"
    assert stderr.splitlines() == [f"rayvr capture: {said}"], stderr[-2000:]
    assert proc.returncode == 128 + sig  # the shell's status for the signal
    assert not (tmp_path / "out").exists()  # the job's folder, made and locked before the cluster, is gone
