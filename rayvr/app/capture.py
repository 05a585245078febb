"""Headless capture: stills, stereo pairs and camera paths to PNG (colour) and NPY (aux), with
format "exr" also the linear HDR colour and the float aux channels as OpenEXR, with format "npy"
the colour as NPY too. Frames are encoded and written on a pool of threads while the next ones
render (app/writers.py)."""
from __future__ import annotations

import ast
import contextlib
import hashlib
import json
import logging
import os
import re
import signal
import socket
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from ..frame.cameras.rig import EYES, Pose, StereoRig, check_camera_positions, load_path, orbit
from ..util.inputs import read_json
from ..util.output import (FORMATS, OutputError, atomic_write_bytes, check_file_prefix, check_output_dir,
                     check_output_files, create_output_dir, openexr, remove_empty_dirs, write_exr, write_npy,
                     write_png)
from .capture_files import aux_file, color_file, file_name, flow_file
from .flow import FLOW_AUX, check_flow_camera, flow_directions, frame_flows, render_order
from .writers import (DEFAULT_PNG_COMPRESSION, FrameWriter, PipelineTimes, check_png_compression, check_writers,
                      default_writers)
from ..renderer import Frame, Renderer
from ..util.signals import handling
from .views import camera_json

log = logging.getLogger(__name__)

EXR_CHANNELS = {1: "Z", 3: "RGB"}  # EXR channel names by components: depth is Z, vectors/colour RGB


class CaptureInterrupted(KeyboardInterrupt):
    """Ctrl-C during a capture; the message says which frames' files were kept."""


@dataclass
class CaptureJob:
    rig: StereoRig
    poses: list[Pose]
    eyes: str = "both"  # both | left | right
    view: str = "color"
    aux: tuple = ()
    out_dir: Path = Path("out")
    prefix: str = "frame"
    format: str = "png"  # FORMATS
    spp: int = 1  # samples accumulated into each frame (each with its own sample index)
    rig_overrides: list | None = None  # per frame: StereoRig fields that differ (a view's intrinsics)
    cameras: bool = False  # also write each eye's camera (intrinsics, camera-to-world) as JSON
    # How the files are written, not what they show (so not part of job_identity: a rerun with
    # other values resumes the same job): zlib level of the PNGs, writer threads (None: one per core).
    png_compression: int = DEFAULT_PNG_COMPRESSION
    writers: int | None = None

    def __post_init__(self):
        check_file_prefix(self.prefix)  # every file stays inside out_dir
        check_png_compression(self.png_compression)
        if self.writers is not None:
            check_writers(self.writers)
        if not (isinstance(self.spp, int) and self.spp >= 1):
            raise ValueError(f"spp must be a positive whole number, got {self.spp!r}")
        if self.format not in FORMATS:
            raise ValueError(f"unknown output format {self.format!r}; allowed: {', '.join(FORMATS)}")
        if self.format == "exr":
            openexr()  # a missing package is one clear error before any rendering
        if self.rig_overrides is not None and len(self.rig_overrides) != len(self.poses):
            raise ValueError(f"{len(self.rig_overrides)} rig overrides for {len(self.poses)} poses")
        if FLOW_AUX in self.aux:
            check_flow_camera(self.rig.camera)  # one line before any rendering

    @property
    def hdr_exr(self) -> bool:
        """Whether the linear HDR colour goes to <prefix>_<eye>.exr (format exr, colour view)."""
        return self.format == "exr" and self.view == "color"

    @property
    def output_aux(self) -> tuple:
        """The aux channels written: the user's, plus the HDR colour for its EXR."""
        return self.aux + ("hdr",) if self.hdr_exr and "hdr" not in self.aux else self.aux

    @property
    def render_aux(self) -> tuple:
        """The aux channels to read back: output_aux; flow (app/flow.py) and distance are made from
        the position."""
        aux = tuple(a for a in self.output_aux if a not in DERIVED_AUX)
        derived = any(a in self.aux for a in DERIVED_AUX)
        return aux + ("position",) if derived and "position" not in aux else aux

    @property
    def writes_transforms(self) -> bool:
        """Whether the job writes transforms.json: a multi-view job's cameras, or a sequence's flow files."""
        return self.cameras or FLOW_AUX in self.aux

    @property
    def eye_names(self) -> list[str]:
        return list(EYES) if self.eyes == "both" else [self.eyes]

    def frame_rig(self, index: int) -> StereoRig:
        """The rig of frame `index`: the job's rig at that pose, with that frame's overrides."""
        extra = self.rig_overrides[index] if self.rig_overrides else None
        return StereoRig(**{**self.rig.__dict__, "pose": self.poses[index], **(extra or {})})


def poses_for(rig: StereoRig, scene, frames: int | None = None, path: str | None = None) -> list[Pose]:
    """The poses a capture renders: a camera path file, an N-frame turntable orbit, or the rig's
    pose; each within the GPU's float32 range of the scene (else ValueError, before any frame)."""
    if path is not None:
        poses, where = load_path(path), f"{path}: pose"
    elif frames is not None and frames > 1:
        target = scene.center if scene.camera is None else rig.pose.position + rig.pose.forward * 2.0
        offset = rig.pose.position - target
        radius = float(np.hypot(offset[0], offset[2])) or 1.0
        poses, where = orbit(target, radius, float(offset[1]), frames,
                             start_deg=float(np.degrees(np.arctan2(offset[0], offset[2])))), "orbit frame"
    else:
        poses, where = [rig.pose], "camera pose"
    check_camera_positions(poses, scene.origin, where)
    return poses


# The distance from the eye to each pixel's surface, the other depth convention beside the `depth`
# aux's (linear view depth along -Z for a planar camera): float32, 0 where no surface is.
DISTANCE_AUX = "distance"
DERIVED_AUX = (FLOW_AUX, DISTANCE_AUX)  # made here from the position, not read back themselves


def ray_distance(position, eye_position, depth) -> np.ndarray:
    """|position - eye| of an eye image's pixels (world), 0 where `depth` says no surface."""
    d = np.linalg.norm(np.asarray(position, np.float64) - np.asarray(eye_position, np.float64), axis=-1)
    return np.where(np.asarray(depth) > 0, d, 0.0).astype(np.float32)


def frame_files(job: CaptureJob, index: int) -> list[Path]:
    """Every file frame `index` of `job` writes: the frame is complete on disk when all exist."""
    out = []
    for eye in job.eye_names:
        out.append(color_file(job, index, eye))
        out += [aux_file(job, index, eye, name) for name in job.output_aux if name != FLOW_AUX]  # (distance's too)
        for direction in flow_directions(job, index):
            out += [flow_file(job, index, eye, direction), flow_file(job, index, eye, direction, mask=True)]
        if job.cameras:
            out.append(file_name(job, index, eye, "camera", "json"))
    return out


def write_frame(job: CaptureJob, index: int, frame: Frame, record: str | None = None,
                neighbours: dict | None = None) -> list[Path]:
    """Write one frame's files, each atomically, and with `record` (a JobFolder's digest) then its
    record; the files written. A sequence's frame loses its record first: until write_record, the
    frame on disk is not finished. With flow, `neighbours` holds the next ("forward") and previous
    ("backward") frames it is flowed to (app/flow.py). Runs on a writer thread (app/writers.py)."""
    written = []
    flows = frame_flows(job, index, frame, neighbours or {}) if FLOW_AUX in job.aux else {}
    if len(job.poses) > 1:
        record_file(job, index).unlink(missing_ok=True)
    rig = job.frame_rig(index) if job.cameras else None
    for eye, img in frame.eyes.items():
        p = color_file(job, index, eye)
        if p.suffix == ".npy":
            write_npy(p, img.color)
        else:
            write_png(p, img.color, job.png_compression)
        written.append(p)
        aux = dict(img.aux)
        if DISTANCE_AUX in job.aux:
            aux[DISTANCE_AUX] = ray_distance(aux["position"], job.frame_rig(index).eye(eye).position, img.depth)
        for name, arr in aux.items():
            if name not in job.output_aux:
                continue  # read back only to make another channel (flow's and distance's position)
            p = aux_file(job, index, eye, name)
            if p.suffix == ".npy":
                write_npy(p, arr)
            else:
                write_exr(p, arr, EXR_CHANNELS[1 if arr.ndim == 2 else arr.shape[-1]])
            written.append(p)
        for direction in flow_directions(job, index):
            flow, valid = flows[eye, direction]
            p = flow_file(job, index, eye, direction)
            if p.suffix == ".npy":
                write_npy(p, flow)
            else:
                write_exr(p, flow, "XY")
            q = flow_file(job, index, eye, direction, mask=True)
            write_npy(q, valid)
            written += [p, q]
        if rig is not None:
            p = file_name(job, index, eye, "camera", "json")
            atomic_write_bytes(p, camera_json(rig.eye(eye)))
            written.append(p)
    if record is not None:
        write_record(job, index, record)
    return written


# ------------------------------------------------------------------ one job per folder; resuming a job

LOCK_NAME = ".rayvr-lock"  # flock()ed by the job writing into the folder; removed as the job ends
MAX_BOOKKEEPING_BYTES = 256 << 20  # a job or record file larger than this was not written by rayvr


def job_file(job: CaptureJob) -> Path:
    return job.out_dir / f"{job.prefix}_job.json"


def record_file(job: CaptureJob, index: int) -> Path:
    """The record of a sequence's frame `index`, written after all of the frame's files: the job's
    identity digest and each file's size and checksum. Resume skips only frames it verifies."""
    return job.out_dir / f"{job.prefix}_{index:04d}_record.json"


def summary_file(job: CaptureJob) -> Path:
    return job.out_dir / f"{job.prefix}_timings.json"


def job_identity(job: CaptureJob, **inputs) -> dict:
    """What makes a job's frames what they are: its frames' rigs and outputs plus `inputs` (scene,
    materials, render settings as RenderSettings.to_dict()). Frames on disk are reused only by a
    job with the same identity."""
    rigs = [job.frame_rig(i) for i in range(len(job.poses))]
    rig_keys = ("ipd", "fov_y", "convergence", "near", "far", "eye_tangents", "size")
    return json.loads(json.dumps({
        "frames": [{**r.pose.to_dict(), **{k: getattr(r, k) for k in rig_keys}, "camera": r.camera.name} for r in rigs],
        "eyes": job.eyes, "view": job.view, "aux": list(job.output_aux), "format": job.format, "spp": job.spp,
        "cameras": job.cameras, **inputs}, default=str))


def identity_digest(identity: dict) -> str:
    """The job named in each frame record: a digest of its identity (job_identity)."""
    return hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()


def _sha256(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def write_record(job: CaptureJob, index: int, digest: str) -> None:
    """Mark frame `index` finished: its files (all written, each atomically) with their sizes and
    checksums, and the job they belong to."""
    files = {f.name: {"bytes": f.stat().st_size, "sha256": _sha256(f)} for f in frame_files(job, index)}
    atomic_write_bytes(record_file(job, index),
                       json.dumps({"job": digest, "frame": index, "files": files}, indent=1).encode())


NO_RECORD = "no record (written by an older rayvr, or stopped mid-frame)"


def _read_json(path: Path):
    """A bookkeeping file's JSON; FileNotFoundError if absent, ValueError if it is not what rayvr writes."""
    if not os.path.lexists(path):
        raise FileNotFoundError(path)
    return read_json(path, "rayvr bookkeeping file", MAX_BOOKKEEPING_BYTES)


def frame_problem(job: CaptureJob, index: int, digest: str, checksums: bool = True) -> str | None:
    """Why frame `index` on disk is not a finished frame of the job `digest` names (None: it is):
    no record, another job's record, or a file that is not the size (or checksum) it records."""
    p = record_file(job, index)
    try:
        record = _read_json(p)
    except FileNotFoundError:
        return NO_RECORD
    except (OSError, ValueError) as exc:
        return f"{p}: unreadable record ({exc})"
    try:
        if record["job"] != digest:
            return f"{p}: the record of another job"
        recorded = record["files"]
        names = sorted(f.name for f in frame_files(job, index))
        if sorted(recorded) != names:
            return f"{p}: the record lists other files"
        for name in names:
            f, want = job.out_dir / name, recorded[name]
            try:
                size = f.stat().st_size
            except OSError:
                return f"{f}: missing"
            if size != want["bytes"]:
                return f"{f}: {size} bytes, its record says {want['bytes']}"
            if checksums and _sha256(f) != want["sha256"]:
                return f"{f}: its checksum differs from its record"
    except (KeyError, TypeError):
        return f"{p}: not a frame record"
    return None


def settings_data(value) -> dict | None:
    """A job identity's render settings as RenderSettings.to_dict() data: the table this rayvr
    writes, or the RenderSettings repr an older rayvr wrote (its values literals); None if neither."""
    import warnings

    from ..settings import RenderSettings

    if isinstance(value, str):
        fields = _repr_fields(value)
        try:
            value = {k: ast.literal_eval(v) for k, v in fields.items()} if fields is not None else None
        except (ValueError, SyntaxError, RecursionError, MemoryError):
            return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # an old file's dof_aperture
            return RenderSettings(**value).to_dict() if isinstance(value, dict) else None
    except (TypeError, ValueError):
        return None


def same_job(recorded, identity: dict) -> bool:
    """Whether a job file's identity is `identity`'s, its settings compared as values (a job file
    of an older rayvr recorded their repr: the same job, to resume)."""
    if recorded == identity:
        return True
    if not isinstance(recorded, dict) or set(recorded) != set(identity) or "settings" not in identity:
        return False
    old = settings_data(recorded["settings"])
    return old is not None and old == settings_data(identity["settings"]) and \
        {**recorded, "settings": None} == {**identity, "settings": None}


def describe_difference(old, new, limit: int = 3) -> str:
    """What differs between two job identities, e.g. "spp 32 -> 1, settings.exposure 4.0 -> 1.0"."""
    found = []
    if isinstance(old, dict) and isinstance(new, dict) and isinstance(old.get("settings"), str):
        old = {**old, "settings": settings_data(old["settings"]) or old["settings"]}  # an older rayvr's repr
    _differences(old, new, "", found)
    more = f" and {len(found) - limit} more" if len(found) > limit else ""
    return ", ".join(found[:limit]) + more if found else "unreadable"


_ABSENT = "(none)"


def _differences(a, b, where: str, found: list) -> None:
    if a == b:
        return
    if isinstance(a, dict) and isinstance(b, dict):
        for k in [*b, *(k for k in a if k not in b)]:
            _differences(a.get(k, _ABSENT), b.get(k, _ABSENT), f"{where}.{k}" if where else str(k), found)
        return
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            short = len(json.dumps(a)) <= 40 and len(json.dumps(b)) <= 40
            found.append(f"{where} {_short(a)} -> {_short(b)}" if short else f"{where}: {len(a)} -> {len(b)} entries")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            _differences(x, y, f"{where}[{i}]", found)
        return
    fields_a, fields_b = _repr_fields(a), _repr_fields(b)  # the settings are a dataclass's repr
    if fields_a is not None and fields_b is not None:
        _differences(fields_a, fields_b, where, found)
        return
    found.append(f"{where} {_short(a)} -> {_short(b)}")


def _repr_fields(value) -> dict | None:
    """The fields of a dataclass repr such as "RenderSettings(exposure=1.0, ...)", else None."""
    if not (isinstance(value, str) and value.endswith(")") and len(value) < 100_000):
        return None
    try:
        call = ast.parse(value, mode="eval").body
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return None
    if not isinstance(call, ast.Call) or call.args:
        return None
    return {k.arg: ast.get_source_segment(value, k.value) for k in call.keywords}


def _short(value) -> str:
    text = value if isinstance(value, str) else json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def lock_folder(folder: Path, why=lambda: "") -> int | None:
    """Hold `folder` for one job: an exclusive flock on its .rayvr-lock, which the kernel drops
    when the process ends, so a crashed job leaves no stale lock. OutputError if a job holds it
    (`why()`, asked only then, ends its message)."""
    path = folder / LOCK_NAME
    try:
        import fcntl
    except ImportError:  # no flock on this platform
        log.warning("%s: cannot lock the output folder here; two jobs writing into it would go unnoticed", folder)
        return None
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
        except OSError as exc:
            raise OutputError(f"{path}: cannot create the output folder's lock file: {exc.strerror or exc}") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode("utf-8", "replace").strip() or "another process"
            os.close(fd)
            raise OutputError(f"{folder}: output folder is busy: another capture ({holder}) is writing into it; "
                              f"wait for it to end or use another --out{why()}") from None
        except OSError as exc:  # a file system without locks
            os.close(fd)
            log.warning("%s: cannot lock the output folder (%s); two jobs writing into it would go unnoticed",
                        folder, exc.strerror or exc)
            return None
        try:
            current = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            current = False
        if current:
            os.ftruncate(fd, 0)
            os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode())
            return fd
        os.close(fd)  # its last holder removed that file as it ended: lock the new one


def unlock_folder(folder: Path, fd: int | None) -> None:
    """Remove the lock file while still holding it (a job that opened it meanwhile sees it gone
    and locks a new one), then let go."""
    if fd is None:
        return
    try:
        os.unlink(folder / LOCK_NAME)
    except OSError:
        pass
    os.close(fd)


class JobFolder:
    """The output folder held by one capture job for its life (`with JobFolder(job, identity) as
    folder:`). On entry, before any rendering: every output name is checked (no folder where a
    file goes), the folder is created and locked (a second job into it is refused: busy), and for
    a sequence with `identity` the job file is checked and written: a folder holding frames of a
    job with another identity is refused (OutputError naming what differs), and with `resume` the
    frames whose records verify (`done`) are skipped; `digest` is what new records must name.
    A job that fails before its first file removes the folder it created. With `overwrite`, the
    sequence frames (and records) of whatever job left them under this prefix are deleted once the
    folder is locked, and every frame is rendered again."""

    def __init__(self, job: CaptureJob, identity: dict | None = None, resume: bool = True, overwrite: bool = False):
        self.job, self.identity, self.overwrite = job, identity, overwrite
        self.sequence = len(job.poses) > 1  # a still is just rendered again
        self.digest = identity_digest(identity) if identity is not None and self.sequence and resume else None
        self.done: set[int] = set()
        self._lock = None
        self._created: list[Path] = []

    def paths(self) -> list[Path]:
        """Every file the job writes into its folder."""
        job = self.job
        out = [job.out_dir / LOCK_NAME, summary_file(job)]
        for i in range(len(job.poses)):
            out += frame_files(job, i)
        if self.sequence:
            out += [job_file(job)] + [record_file(job, i) for i in range(len(job.poses))]
        if job.writes_transforms:
            out.append(job.out_dir / "transforms.json")  # views.write_transforms
        return out

    def __enter__(self) -> "JobFolder":
        job = self.job
        check_output_dir(job.out_dir)
        check_output_files(self.paths())
        self._created = create_output_dir(job.out_dir)
        try:
            self._lock = lock_folder(job.out_dir, why=self._how_the_job_file_differs)
            if self.overwrite and self.sequence:
                for name in self._frame_files_on_disk():  # the user asked: no frame of theirs is kept
                    (job.out_dir / name).unlink(missing_ok=True)
            if self.identity is not None and self.sequence:
                self._adopt(self._refuse_another_job())
                if self.digest is not None:
                    self.done = self._verified_frames()
                atomic_write_bytes(job_file(job), json.dumps(self.identity, indent=1, allow_nan=False).encode())
        except BaseException:
            self._release(failed=True)
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self._release(failed=exc_type is not None)

    def _release(self, failed: bool) -> None:
        unlock_folder(self.job.out_dir, self._lock)
        self._lock = None
        if failed and self._created:  # the folder is this job's: keep it only if a frame's file is in it
            leftover = job_file(self.job)
            try:
                if set(os.listdir(self.job.out_dir)) <= {leftover.name}:
                    leftover.unlink(missing_ok=True)
                    remove_empty_dirs(self._created)
            except OSError:  # gone, or no longer ours to list: leave it
                pass

    def _how_the_job_file_differs(self) -> str:
        """For a busy folder's message: how the job its job file names differs from this one."""
        p = job_file(self.job)
        if self.identity is None or not self.sequence or not p.is_file():
            return ""
        try:
            recorded = _read_json(p)
        except (OSError, ValueError):
            return ""
        if same_job(recorded, self.identity):
            return ""
        return f" ({p.name} -> this job: {describe_difference(recorded, self.identity)})"

    def _frame_files_on_disk(self) -> list[str]:
        """Names of sequence frame files (of any job) with this prefix: PREFIX_NNNN_*."""
        pattern = re.compile(rf"{re.escape(self.job.prefix)}_\d{{4,}}_")  # file_name's frame numbers
        return [name for name in os.listdir(self.job.out_dir) if pattern.match(name)]

    def _adopt(self, recorded: dict | None) -> None:
        """Resume the same job written down by an older rayvr: its frames' records name the digest
        of the identity as that job file has it."""
        if recorded is not None and recorded != self.identity:
            self.identity = recorded
            if self.digest is not None:
                self.digest = identity_digest(recorded)

    def _refuse_another_job(self) -> dict | None:
        """OutputError if the folder holds frames of another job; the job file's identity if it is
        this job's (None: no job file, or one that left no frame)."""
        p = job_file(self.job)
        try:
            recorded = _read_json(p)
        except FileNotFoundError:
            return None
        except (OSError, ValueError):
            recorded = None  # a job nobody can name
        if recorded is not None and same_job(recorded, self.identity):
            return recorded
        if not self._frame_files_on_disk():
            return None  # one that left no frame: this one takes the folder
        what = describe_difference(recorded, self.identity) if isinstance(recorded, dict) else "unreadable"
        raise OutputError(f"{self.job.out_dir}: holds frames of another job ({p.name} -> this job: {what}); "
                          f"use another --out or --prefix, or --overwrite to render every frame again in their "
                          f"place")

    def _verified_frames(self) -> set[int]:
        """The frames whose records verify; one warning for those on disk that do not."""
        done, failed = set(), []
        for i in range(len(self.job.poses)):
            problem = frame_problem(self.job, i, self.digest)
            if problem is None:
                done.add(i)
            elif problem != NO_RECORD or any(f.exists() for f in frame_files(self.job, i)):
                failed.append((i, problem))
        if failed:
            log.warning("%s: %d frame(s) on disk are not verified and are rendered again (frame %d: %s)",
                        self.job.out_dir, len(failed), *failed[0])
        return done


@contextlib.contextmanager
def interrupts_between_frames():
    """Ctrl-C during a capture takes effect between frames: the first SIGINT is noted and the
    returned `check()` raises KeyboardInterrupt at the next safe point, so no file is being
    written or left out of the count; a second SIGINT interrupts at once."""
    noted = []

    def on_sigint(signum, frame):
        if noted:
            raise KeyboardInterrupt
        noted.append(signum)

    def check() -> None:
        if noted:
            raise KeyboardInterrupt

    with handling(signal.SIGINT, on_sigint):
        yield check


def run_capture(renderer: Renderer, job: CaptureJob, progress: bool = True, on_frame=None,
                identity: dict | None = None, resume: bool = True, folder: JobFolder | None = None) -> dict:
    """Render the frames of `job`, write the files, return a summary (files, GPU ms per pass).
    The output folder is held for the run (JobFolder of `identity` and `resume`) unless the
    caller holds it (`folder`). With an identity (job_identity), frames a previous run of the same
    job finished, whose files match their records, are skipped and counted."""
    if folder is None:
        with JobFolder(job, identity, resume) as folder:
            return run_capture(renderer, job, progress, on_frame, folder=folder)
    indices = [i for i in range(len(job.poses)) if i not in folder.done]
    summary = render_frames(renderer, job, indices, progress, on_frame, record=folder.digest,
                            skipped=len(folder.done))
    if job.writes_transforms:  # the views' cameras, the flow files of each frame
        from .views import write_transforms

        write_transforms(job, renderer.scene.material_names())
    return summary


def render_frames(renderer: Renderer, job: CaptureJob, indices: list[int], progress: bool = False, on_frame=None,
                  record: str | None = None, skipped: int = 0) -> dict:
    """Render frames `indices` of `job` into its folder (which the caller holds: JobFolder) and
    return the summary; `on_frame(index)` is called, in order, once each frame's files are
    written. With `record` (a JobFolder's digest), each finished frame gets its record.

    The GPU renders frame i+1 while frame i is read back (Renderer.render_sequence) and frames
    before it are encoded and written on job.writers threads (FrameWriter: at most its limit of
    frames in memory); one writer writes each frame here, in turn (the serial path)."""
    files, timings, unavailable, ran = [], [], set(), {}
    order = render_order(job, indices)  # with flow also the neighbours of the frames written (not written)
    writes = set(indices)
    rigs = [job.frame_rig(i) for i in order]
    if rigs:  # what the frames' plan refuses (Renderer.plan) is one line before any work, no progress bar
        renderer.plan(len(rigs[0].eyes(job.eyes)), job.view, rigs[0].camera)
    bar = None
    if progress and len(indices) * job.spp > 1:
        from tqdm import tqdm

        # with --spp the bar counts samples: one frame of many samples is long work too
        bar = tqdm(total=len(order) * job.spp, unit="sample" if job.spp > 1 else "frame", desc="capture")
    threads = max(1, min(job.writers or default_writers(), len(indices)))  # no pool for a still
    clock = PipelineTimes(renderer.reader, meaningful=not renderer.gl.is_software)
    written = 0

    def finished(frames) -> None:
        nonlocal written
        for i, frame_files_written in frames:
            files.extend(frame_files_written)
            written += 1
            if on_frame is not None:
                on_frame(i)

    with FrameWriter(threads) as writer:
        try:
            with interrupts_between_frames() as check_interrupt:
                frames = renderer.render_sequence(rigs, eyes=job.eyes, view=job.view, aux=job.render_aux, depth=False,
                                                  spp=job.spp, progress=bar.update if bar else None)
                window: dict = {}  # with flow: the frames rendered last, which the frames written flow to
                for k in order:
                    with clock.rendering():
                        frame = next(frames)
                    check_interrupt()
                    if k in writes:
                        timings.append(frame.timings)
                        unavailable.update(frame.timings_unavailable)
                        ran.update(dict.fromkeys(frame.passes))
                    window[k] = frame
                    del frame  # the writer holds it until it is written: the queue bounds the memory
                    for i in _ready(job, k, writes, window):
                        neighbours = {d: window[i + 1 if d == "forward" else i - 1] for d in flow_directions(job, i)}
                        with clock.writing():
                            finished(writer.submit(i, partial(write_frame, job, i, window[i], record, neighbours)))
                        clock.frame_done(frame_gpu_ms=sum(window[i].timings.values()))
                    keep = k - 1 if FLOW_AUX in job.aux else k + 1  # the frame before k: k + 1's backward flow
                    for j in [j for j in window if j < keep]:
                        del window[j]
                    if bar is not None:
                        bar.set_postfix_str(clock.describe(), refresh=False)
                    check_interrupt()
                with clock.writing():
                    finished(writer.finish())
        except KeyboardInterrupt:
            # Every file is written atomically, so what is there is whole: say what was kept.
            finished(writer.settle())
            raise CaptureInterrupted(f"interrupted after {written} of {len(indices)} frame(s); "
                                     f"the {len(files)} file(s) written are kept in {job.out_dir}/") from None
        finally:
            if bar is not None:
                bar.close()
    return summarize(job, renderer.gl.info()["renderer"], not renderer.gl.is_software, files, timings, ran,
                     unavailable, written=len(indices), skipped=skipped,
                     denoise=list(renderer.plan().denoise) if renderer.settings.denoise else [],
                     stereo=renderer.settings.stereo,
                     stereo_counts=renderer.stereo_counts(),  # the last frame's reused pixels or holes
                     pipeline=clock.summary(writer, job.png_compression))


def _ready(job: CaptureJob, k: int, writes: set, window: dict) -> list[int]:
    """The frames to write once frame `k` is rendered: `k` itself, or with flow the frame before
    it (whose next frame `k` is) and `k` if it is the sequence's last."""
    if FLOW_AUX not in job.aux:
        return [k] if k in writes else []
    ready = [k - 1] if k - 1 in writes and k - 1 in window else []
    return ready + ([k] if k in writes and k == len(job.poses) - 1 else [])


def summarize(job: CaptureJob, gl: str, meaningful: bool, files, timings, ran, unavailable, **counts) -> dict:
    """The summary a capture writes to <prefix>_timings.json (counts: written, skipped, ...; denoise)."""
    passes = sorted({k for t in timings for k in t})
    mean = {k: float(np.mean([t[k] for t in timings if k in t])) for k in passes}
    return {"frames": len(job.poses), **counts, "files": [str(f) for f in files], "gpu_ms_mean": mean,
            "gpu_ms_per_frame": timings, "gl": gl, "timings_meaningful": meaningful,
            "passes": list(ran), "gpu_ms_unavailable": sorted(unavailable),  # timers that read back garbage
            "size": list(job.rig.size), "eyes": job.eyes, "spp": job.spp,
            "gpu_ms_note": "per sample (the last of each frame's samples)" if job.spp > 1 else "per frame"}


def write_summary(job: CaptureJob, summary: dict) -> Path:
    p = summary_file(job)
    atomic_write_bytes(p, json.dumps(summary, indent=1, allow_nan=False).encode())
    return p
