"""Captures and benchmark sweeps spread over several GPUs or hosts with Ray (`rayvr[cluster]`).

One Ray actor per worker holds a GL context pinned to the GPU Ray gave it (CUDA_VISIBLE_DEVICES
mapped to an EGL device: context.assigned_egl_device) and a Renderer, so the scene is loaded and
its BVH built once per worker, not per frame. Work goes out in tasks (chunks of frames, sweep
variants), at most two in flight per worker; a worker that dies is restarted by Ray and its task
goes back into the queue for whichever worker is free next, with the frames already on disk left
out. On a machine without GPUs the workers are CPU processes, each with its own llvmpipe context.

Workers write frames straight into the output folder through the single-process capture's
pipeline (app/writers.py: a bounded pool of writer threads in each worker, every file atomically),
so on several hosts the folder must be shared storage mounted at the same path.
"""
from __future__ import annotations

import logging
import math
import os
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass

log = logging.getLogger(__name__)

CLUSTER_EXTRA = "pip install 'rayvr[cluster]'"
MAX_RESTARTS = 3  # Ray restarts a dead worker this often before it is given up
MAX_ATTEMPTS = 4  # a task is tried this often (the first run plus retries) before its frames count as failed
IN_FLIGHT = 2  # tasks queued per worker: the next one is there when the current one ends
MAX_WORKERS = 1024
DEFAULT_CONNECT_TIMEOUT_S = 30.0  # --connect-timeout: Ray itself retries an unreachable cluster for minutes
# Ray frees a killed actor's CPU or GPU a moment after ray.kill returns: workers closed just before
# (bench workers 1,2 on one cluster) are waited for this long before the cluster counts as full.
RESOURCE_WAIT_S = 10.0


class ClusterError(RuntimeError):
    """Ray is missing, cannot start, or the cluster cannot hold the workers asked for."""


def require_ray():
    """The ray module, or one ClusterError naming the extra that brings it."""
    try:
        import ray
    except ImportError:
        raise ClusterError(f"--workers needs Ray, which is not installed: {CLUSTER_EXTRA}") from None
    return ray


def _host_port(address: str) -> tuple[str, int] | None:
    """(host, port) of a HOST:PORT address ([v6]:PORT too); None for 'auto', ray://... and the like."""
    host, sep, port = address.rpartition(":")
    if not sep or not host or "/" in address or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def _reach(address: str, timeout: float) -> None:
    """A TCP connection to HOST:PORT within `timeout` seconds, else one ClusterError: Ray's own
    connect retries for minutes, printing gRPC warnings."""
    where = _host_port(address)
    if where is None:
        return
    try:
        socket.create_connection(where, timeout=timeout).close()
    except socket.timeout:
        raise ClusterError(f"cannot reach Ray at {address}: no answer within {timeout:g} s "
                           f"(--connect-timeout)") from None
    except OSError as exc:  # refused: nothing listens there; unknown host; no route
        raise ClusterError(f"cannot reach Ray at {address}: {exc.strerror or exc}") from None


class _StderrHidden:
    """fd 2 goes to /dev/null while Ray connects: its C++ client logs every failed gRPC attempt
    there (the one error line that follows says what went wrong)."""

    def __enter__(self):
        self.saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)
        return self

    def __exit__(self, *exc):
        os.dup2(self.saved, 2)
        os.close(self.saved)


_left_behind = threading.Event()


def connect_left_behind() -> bool:
    """Whether a ray.init(address=...) was given up while it still ran. Its daemon thread would
    end with the process, but Ray's exit handler (ray.shutdown, at interpreter exit) can wait on
    it for ever: a process that gave one up ends with os._exit once its own clean-up is done."""
    return _left_behind.is_set()


def _connect(ray, address: str, timeout: float, **kw) -> None:
    """ray.init(address=...) within `timeout` seconds, else one ClusterError. The connection is
    made on a daemon thread: this one waits in a join that Ctrl-C and SIGTERM interrupt, where
    Ray's own wait blocks in C++ and would hold them off."""
    _reach(address, timeout)
    failure = []

    def connect():
        try:
            ray.init(address=address, **kw)
        except BaseException as exc:  # reported by the waiting thread
            failure.append(exc)

    thread = threading.Thread(target=connect, name="rayvr-ray-connect", daemon=True)
    try:
        with _StderrHidden():
            thread.start()
            thread.join(timeout)
    finally:
        if thread.is_alive():  # Ctrl-C, SIGTERM or the timeout: see connect_left_behind
            _left_behind.set()
    if thread.is_alive():
        raise ClusterError(f"no Ray cluster answered at {address} within {timeout:g} s (--connect-timeout)")
    if failure:
        raise failure[0]


@dataclass
class WorkerSpec:
    """What each worker loads once: the capture's scene, config and settings (scene None: the
    built-in room), or nothing for sweep workers (they load the scenes a sweep names)."""

    scene: str | None = None
    materials: object = None  # a path or a MaterialConfig
    settings: object = None  # RenderSettings
    backend: str | None = None
    capture: bool = True


class RenderWorker:
    """The body of a Ray actor (wrapped with ray.remote by Cluster)."""

    def __init__(self, spec: WorkerSpec):
        from ..gl.context import assigned_egl_device, create_context

        self.spec = spec
        self.egl_device = assigned_egl_device()
        self.gl = create_context(spec.backend, device_index=self.egl_device)
        self.renderer = None
        self.scenes = {}  # scene name -> Scene, for sweeps (measure)
        self.pool = None
        if spec.capture:
            from ..renderer import Renderer

            self.renderer = Renderer(spec.scene, spec.materials, gl=self.gl, settings=spec.settings)

    def info(self) -> dict:
        import socket

        return {"host": socket.gethostname(), "pid": os.getpid(), "egl_device": self.egl_device,
                "cuda_visible_devices": os.environ.get("CUDA_VISIBLE_DEVICES"), "gl": self.gl.info()["renderer"]}

    def capture(self, job, frames: list[int], crash_file: str | None = None, record: str | None = None) -> dict:
        """Render and write `frames` of `job` (the caller holds its folder), each with its record
        when `record` names the job (JobFolder.digest). Test hook: with `crash_file`, the first
        worker to finish a frame makes that file and dies at once (as a host losing power would)."""
        from .capture import render_frames

        def after_frame(index):
            try:
                os.close(os.open(crash_file, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                return
            os._exit(1)

        return render_frames(self.renderer, job, frames, on_frame=after_frame if crash_file else None, record=record)

    def measure(self, load_scene, scene_name: str, rig, variant, repeat: int):
        """A variant measured on this worker's GPU (rayvr.quality.measure.measure), in the scene
        `load_scene(scene_name)` gives ((scene, _), or (None, why it is missing)), loaded once per name."""
        from ..quality.measure import RendererPool, measure

        if scene_name not in self.scenes:
            scene, why = load_scene(scene_name)
            if scene is None:
                raise ValueError(f"worker on {self.info()['host']}: scene {scene_name}: {why}")
            self.scenes[scene_name] = scene
        self.pool = self.pool or RendererPool(self.gl)
        return measure(self.gl, self.scenes[scene_name], rig, variant, repeat, pool=self.pool)


def _dead_worker_errors(ray) -> tuple:
    ex = ray.exceptions
    return tuple(getattr(ex, n) for n in ("RayActorError", "WorkerCrashedError", "ActorUnavailableError",
                                          "ActorDiedError") if hasattr(ex, n))


def _unavailable_errors(ray) -> tuple:
    """A restarting worker answers with these: it is not dead, only not back yet."""
    return tuple(getattr(ray.exceptions, n) for n in ("ActorUnavailableError",) if hasattr(ray.exceptions, n))


def _free_resources(ray, workers: int, wait_s: float) -> tuple[dict, int, int]:
    """(the cluster's resources, free GPUs, free CPUs), once `workers` fit or after `wait_s` seconds."""
    deadline = time.monotonic() + wait_s
    while True:
        total, free = ray.cluster_resources(), ray.available_resources()
        gpus, cpus = int(free.get("GPU", 0)), int(free.get("CPU", 0))
        if (gpus if total.get("GPU", 0) else cpus) >= workers or time.monotonic() >= deadline:
            return total, gpus, cpus
        time.sleep(0.1)


class Cluster:
    """N Ray workers (actors), on a local Ray started here or the cluster at `address` (reached
    within `connect_timeout` seconds)."""

    def __init__(self, workers: int, spec: WorkerSpec, address: str | None = None,
                 connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S):
        ray = self.ray = require_ray()
        if not 1 <= workers <= MAX_WORKERS:
            raise ClusterError(f"--workers must be from 1 to {MAX_WORKERS}, got {workers}")
        self.started = False
        if not ray.is_initialized():
            kw = dict(include_dashboard=False, logging_level=logging.ERROR, log_to_driver=False)
            try:
                if address:
                    _connect(ray, address, connect_timeout, **kw)
                else:  # a local Ray: one process per worker, even on fewer cores
                    ray.init(num_cpus=max(os.cpu_count() or 1, workers), **kw)
            except ClusterError:
                raise
            except Exception as exc:  # Ray raises ConnectionError, RuntimeError, ValueError...
                where = f"at {address}" if address else "locally"
                raise ClusterError(f"cannot start Ray {where}: {str(exc).splitlines()[0] if str(exc) else exc!r}") from None
            self.started = True
        # What is free: workers that do not fit would wait for resources for ever.
        total, gpus, cpus = _free_resources(ray, workers, RESOURCE_WAIT_S)
        if total.get("GPU", 0):
            if workers > gpus:
                self.close()
                raise ClusterError(f"--workers {workers} needs {workers} GPUs; the Ray cluster has {gpus} free "
                                   f"of {int(total['GPU'])}")
            options = {"num_gpus": 1, "num_cpus": 0}
        else:
            if workers > cpus:
                self.close()
                raise ClusterError(f"--workers {workers} needs {workers} CPUs; the Ray cluster has {cpus} free "
                                   f"of {int(total.get('CPU', 0))} (and no GPU)")
            options = {"num_cpus": 1}
        self.uses_gpus = bool(gpus)
        actor = ray.remote(RenderWorker).options(max_restarts=MAX_RESTARTS, max_task_retries=0, **options)
        self.actors = [actor.remote(spec) for _ in range(workers)]
        self.dead_errors, self.unavailable = _dead_worker_errors(ray), _unavailable_errors(ray)

    def ready(self) -> list[dict]:
        """Wait until every worker has loaded its scene; where each one runs."""
        try:
            return self._get([a.info.remote() for a in self.actors])
        except self.dead_errors as exc:  # its constructor failed (no GL context, no EGL device, no scene)
            lines = [ln for ln in str(exc).splitlines() if "Error" in ln]
            raise ClusterError(f"a worker could not start: {(lines or [type(exc).__name__])[-1].strip()}") from None

    def _get(self, refs):
        try:
            return self.ray.get(refs)
        except self.ray.exceptions.RayTaskError as exc:  # the worker's own exception, without Ray's wrapping
            raise (exc.cause if isinstance(getattr(exc, "cause", None), Exception) else ClusterError(str(exc).splitlines()[0])) from None

    def run(self, tasks: list, submit, size=lambda t: 1, retry=lambda t: t, bar=None, on_result=None):
        """Run every task on the workers: `submit(actor, task)` returns an ObjectRef. A task whose
        worker died goes back into the queue as `retry(task)` (None: nothing left to do), at most
        MAX_ATTEMPTS runs; `on_result(result)` is called as each task's result arrives. Returns
        (results by task index, units retried, indices of failed tasks)."""
        queue = deque((i, t, 1) for i, t in enumerate(tasks))
        load = {k: 0 for k in range(len(self.actors))}
        deaths = {k: 0 for k in load}
        restarting = {}  # worker -> the ping that answers once Ray has restarted it
        flight, results, failed, retried = {}, {}, [], 0
        while queue or flight:
            for k in sorted(load, key=load.get):  # the least loaded live worker first
                while queue and load[k] < IN_FLIGHT and deaths[k] <= MAX_RESTARTS and k not in restarting:
                    i, t, attempt = queue.popleft()
                    flight[submit(self.actors[k], t)] = (k, i, t, attempt)
                    load[k] += 1
            if not flight:  # every worker is gone
                failed += [i for i, _, _ in queue]
                break
            (ref,), _ = self.ray.wait(list(flight), num_returns=1)
            k, i, t, attempt = flight.pop(ref)
            if i is None:  # a restarted worker answered its ping (or is gone for good)
                try:
                    self._get(ref)
                    restarting.pop(k)
                except self.unavailable:  # still restarting: ask again
                    restarting[k] = ping = self.actors[k].info.remote()
                    flight[ping] = (k, None, None, 0)
                except self.dead_errors:
                    restarting.pop(k)
                    deaths[k] = MAX_RESTARTS + 1
                continue
            load[k] -= 1
            try:
                results[i] = self._get(ref)
            except self.dead_errors as exc:
                if k not in restarting and deaths[k] <= MAX_RESTARTS:  # its other tasks fail too: one death
                    deaths[k] += 1
                    log.warning("worker %d died (%s); its task goes to the next free worker", k, type(exc).__name__)
                    if deaths[k] <= MAX_RESTARTS:
                        restarting[k] = ping = self.actors[k].info.remote()
                        flight[ping] = (k, None, None, 0)
                again = retry(t)
                if again is None:
                    continue
                if attempt >= MAX_ATTEMPTS:
                    failed.append(i)
                    continue
                retried += size(again)
                queue.appendleft((i, again, attempt + 1))
                continue
            if on_result is not None:
                on_result(results[i])
            if bar is not None:
                bar.update(size(t))
        return results, retried, failed

    def close(self) -> None:
        for a in getattr(self, "actors", ()):
            try:
                self.ray.kill(a)
            except Exception:  # already gone
                pass
        self.actors = []
        if self.started:
            self.ray.shutdown()
            self.started = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def chunks(frames: list[int], workers: int, chunk: int | None = None) -> list[list[int]]:
    """Frames in consecutive chunks (a worker's Renderer pipelines inside a chunk): about four per
    worker so a slow worker holds up little, at most 32 frames each."""
    size = chunk or max(1, min(32, math.ceil(len(frames) / (4 * workers))))
    return [frames[k:k + size] for k in range(0, len(frames), size)]


def run_capture_distributed(cluster: Cluster, job, identity: dict | None = None, progress: bool = True,
                            chunk: int | None = None, crash_file: str | None = None, resume: bool = True,
                            folder=None) -> dict:
    """rayvr.app.capture.run_capture over the cluster's workers: the same files, the same summary,
    plus the counts of frames written, skipped (already on disk), retried and failed. This process
    holds the output folder (a capture.JobFolder, or the caller's `folder`) while the workers write."""
    from .capture import JobFolder, frame_files, frame_problem, summarize
    from .writers import describe_ms, merge_pipelines

    if folder is None:
        with JobFolder(job, identity, resume) as folder:
            return run_capture_distributed(cluster, job, progress=progress, chunk=chunk, crash_file=crash_file,
                                           folder=folder)
    n = len(job.poses)
    done, digest = folder.done, folder.digest
    todo = [i for i in range(n) if i not in done]

    def complete(i):  # the workers just wrote them: records and sizes, no checksums read back
        if digest is None:
            return all(f.exists() for f in frame_files(job, i))
        return frame_problem(job, i, digest, checksums=False) is None

    job_ref = cluster.ray.put(job)
    bar = None
    if progress and todo:
        from tqdm import tqdm

        bar = tqdm(total=len(todo), unit="frame", desc=f"capture ({len(cluster.actors)} workers)")
    arrived = []

    def on_result(part):  # where the workers' time goes, on the bar
        arrived.append(part.get("pipeline"))
        if bar is not None and merge_pipelines(arrived):
            bar.set_postfix_str(describe_ms(merge_pipelines(arrived)["ms_per_frame"]), refresh=False)

    try:
        results, retried, failed = cluster.run(
            chunks(todo, len(cluster.actors), chunk),
            lambda actor, c: actor.capture.remote(job_ref, c, crash_file, digest), size=len,
            retry=lambda c: [i for i in c if not complete(i)] or None, bar=bar, on_result=on_result)
    finally:
        if bar is not None:
            bar.close()
    parts = [results[k] for k in sorted(results)]
    files = [f for p in parts for f in p["files"]]
    timings = [t for p in parts for t in p["gpu_ms_per_frame"]]
    ran = {name: None for p in parts for name in p["passes"]}
    unavailable = {name for p in parts for name in p["gpu_ms_unavailable"]}
    missing = [i for i in range(n) if not complete(i)]
    gl = parts[0]["gl"] if parts else None
    meaningful = all(p["timings_meaningful"] for p in parts)
    summary = summarize(job, gl, meaningful, files, timings, ran, unavailable, written=len(timings),
                        skipped=len(done), retried=retried, failed=len(missing), workers=len(cluster.actors),
                        denoise=parts[0]["denoise"] if parts else [],
                        stereo=parts[0]["stereo"] if parts else None,
                        stereo_counts=parts[-1]["stereo_counts"] if parts else {},
                        pipeline=merge_pipelines([p.get("pipeline") for p in parts]))
    summary["missing_frames"] = missing
    return summary


def sweep_measurer(cluster: Cluster, load_scene, scene_name: str, rig, repeat: int):
    """A `measure_all(variants, bar)` as rayvr.quality.measure.local_measurer's: each variant measured on a
    free worker (a dead worker's variant again on another) in the scene `load_scene(scene_name)`
    gives there (a module-level function: the workers import it); yields the results in the
    variants' order."""
    def measure_all(variants, bar=None):
        rig_ref = cluster.ray.put(rig)
        results, _, failed = cluster.run(
            list(variants), lambda actor, v: actor.measure.remote(load_scene, scene_name, rig_ref, v, repeat), bar=bar)
        if failed:
            raise ClusterError(f"{len(failed)} variant(s) of {scene_name} failed on every worker they were tried on")
        for k in range(len(results)):
            yield results[k]
    return measure_all
