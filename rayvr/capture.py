"""Headless capture: stills, stereo pairs and camera paths to PNG (colour) and NPY (aux), or with
format "exr" also the linear HDR colour and the float aux channels as OpenEXR."""
from __future__ import annotations

import contextlib
import json
import logging
import signal
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .camera import EYES, Pose, StereoRig, load_path, orbit
from .output import (FORMATS, atomic_write_bytes, check_file_prefix, check_output_dir, make_output_dir,
                     openexr, write_exr, write_npy, write_png)
from .readback import INTEGER_AUX
from .renderer import Frame, Renderer

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

    def __post_init__(self):
        check_file_prefix(self.prefix)  # every file stays inside out_dir
        if not (isinstance(self.spp, int) and self.spp >= 1):
            raise ValueError(f"spp must be a positive whole number, got {self.spp!r}")
        if self.format not in FORMATS:
            raise ValueError(f"unknown output format {self.format!r}; allowed: {', '.join(FORMATS)}")
        if self.format == "exr":
            openexr()  # a missing package is one clear error before any rendering
        if self.rig_overrides is not None and len(self.rig_overrides) != len(self.poses):
            raise ValueError(f"{len(self.rig_overrides)} rig overrides for {len(self.poses)} poses")

    @property
    def hdr_exr(self) -> bool:
        """Whether the linear HDR colour goes to <prefix>_<eye>.exr (format exr, colour view)."""
        return self.format == "exr" and self.view == "color"

    @property
    def render_aux(self) -> tuple:
        """The aux channels to read back: the user's, plus the HDR colour for its EXR."""
        return self.aux + ("hdr",) if self.hdr_exr and "hdr" not in self.aux else self.aux

    @property
    def eye_names(self) -> list[str]:
        return list(EYES) if self.eyes == "both" else [self.eyes]

    def frame_rig(self, index: int) -> StereoRig:
        """The rig of frame `index`: the job's rig at that pose, with that frame's overrides."""
        extra = self.rig_overrides[index] if self.rig_overrides else None
        return StereoRig(**{**self.rig.__dict__, "pose": self.poses[index], **(extra or {})})


def poses_for(rig: StereoRig, scene, frames: int | None = None, path: str | None = None) -> list[Pose]:
    """The poses a capture renders: a camera path file, an N-frame turntable orbit, or the rig's pose."""
    if path is not None:
        return load_path(path)
    if frames is not None and frames > 1:
        target = scene.center if scene.camera is None else rig.pose.position + rig.pose.forward * 2.0
        offset = rig.pose.position - target
        radius = float(np.hypot(offset[0], offset[2])) or 1.0
        return orbit(target, radius, float(offset[1]), frames,
                     start_deg=float(np.degrees(np.arctan2(offset[0], offset[2]))))
    return [rig.pose]


def file_name(job: CaptureJob, index: int, eye: str, kind: str, ext: str) -> Path:
    frame = f"_{index:04d}" if len(job.poses) > 1 else ""
    suffix = "" if kind == "color" else f"_{kind}"
    return job.out_dir / f"{job.prefix}{frame}_{eye}{suffix}.{ext}"


def aux_file(job: CaptureJob, index: int, eye: str, name: str) -> Path:
    """Where aux channel `name` of an eye goes: NPY, or EXR for float channels with format exr
    (integer IDs stay exact in NPY); the HDR colour of an EXR job is the colour's EXR twin."""
    if name == "hdr" and job.hdr_exr:
        return file_name(job, index, eye, "color", "exr")
    exr = job.format == "exr" and name not in INTEGER_AUX
    return file_name(job, index, eye, name, "exr" if exr else "npy")


def frame_files(job: CaptureJob, index: int) -> list[Path]:
    """Every file frame `index` of `job` writes: the frame is complete on disk when all exist."""
    out = []
    for eye in job.eye_names:
        out.append(file_name(job, index, eye, "color" if job.view == "color" else job.view, "png"))
        out += [aux_file(job, index, eye, name) for name in job.render_aux]
        if job.cameras:
            out.append(file_name(job, index, eye, "camera", "json"))
    return out


def write_frame(job: CaptureJob, index: int, frame: Frame, written: list[Path]) -> None:
    """Write one frame's files, appending each to `written` as soon as it is whole."""
    make_output_dir(job.out_dir)  # only now: a run that fails before leaves no empty folder
    rig = job.frame_rig(index) if job.cameras else None
    for eye, img in frame.eyes.items():
        p = file_name(job, index, eye, "color" if job.view == "color" else job.view, "png")
        write_png(p, img.color)
        written.append(p)
        for name, arr in img.aux.items():
            p = aux_file(job, index, eye, name)
            if p.suffix == ".npy":
                write_npy(p, arr)
            else:
                write_exr(p, arr, EXR_CHANNELS[1 if arr.ndim == 2 else arr.shape[-1]])
            written.append(p)
        if rig is not None:
            from .views import camera_record

            p = file_name(job, index, eye, "camera", "json")
            atomic_write_bytes(p, json.dumps(camera_record(rig.eye(eye)), indent=1).encode())
            written.append(p)


# ------------------------------------------------------------------ resuming a job

def job_file(job: CaptureJob) -> Path:
    return job.out_dir / f"{job.prefix}_job.json"


def job_identity(job: CaptureJob, **inputs) -> dict:
    """What makes a job's frames what they are: its frames' rigs and outputs plus `inputs` (scene,
    materials, render settings). Frames on disk are reused only by a job with the same identity."""
    rigs = [job.frame_rig(i) for i in range(len(job.poses))]
    rig_keys = ("ipd", "fov_y", "convergence", "near", "far", "eye_tangents", "size")
    return json.loads(json.dumps({
        "frames": [{**r.pose.to_dict(), **{k: getattr(r, k) for k in rig_keys}, "camera": r.camera.name} for r in rigs],
        "eyes": job.eyes, "view": job.view, "aux": list(job.render_aux), "format": job.format, "spp": job.spp,
        "cameras": job.cameras, **inputs}, default=str))


def frames_done(job: CaptureJob, identity: dict) -> set[int]:
    """The frames a rerun of the same job can skip: every one of their files is on disk (each file
    was written atomically, so one that exists is whole) and the job file says the same identity.
    A different identity (other settings, scene or config) reuses nothing."""
    p = job_file(job)
    try:
        same = json.loads(p.read_text()) == identity
    except (OSError, ValueError):
        return set()
    if not same:
        log.info("%s: written by a different job; rendering every frame again", p)
        return set()
    return {i for i in range(len(job.poses)) if all(f.exists() for f in frame_files(job, i))}


def write_job_file(job: CaptureJob, identity: dict) -> None:
    """Record the job's identity before its first frame, so an interrupted run can be resumed."""
    make_output_dir(job.out_dir)
    atomic_write_bytes(job_file(job), json.dumps(identity, indent=1).encode())


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

    if threading.current_thread() is not threading.main_thread():  # signals go to the main thread only
        yield check
        return
    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield check
    finally:
        signal.signal(signal.SIGINT, previous)


def run_capture(renderer: Renderer, job: CaptureJob, progress: bool = True, frames=None, on_frame=None,
                identity: dict | None = None) -> dict:
    """Render the poses of `job` (all, or the indices in `frames`), write the files, return a
    summary (files, GPU ms per pass). `on_frame(index)` is called after each frame's files are
    written. With `identity` (job_identity), frames a previous run of the same job completed are
    skipped and counted."""
    check_output_dir(job.out_dir)
    indices = list(range(len(job.poses)) if frames is None else frames)
    skipped = []
    if identity is not None and len(job.poses) > 1:  # a sequence can be resumed; a still is just rendered
        done = frames_done(job, identity)
        skipped = [i for i in indices if i in done]
        indices = [i for i in indices if i not in done]
        write_job_file(job, identity)
    files, timings, unavailable, ran = [], [], set(), {}
    bar = None
    if progress and len(indices) * job.spp > 1:
        from tqdm import tqdm

        # with --spp the bar counts samples: one frame of many samples is long work too
        bar = tqdm(total=len(indices) * job.spp, unit="sample" if job.spp > 1 else "frame", desc="capture")
    rigs = [job.frame_rig(i) for i in indices]
    done = 0
    try:
        with interrupts_between_frames() as check_interrupt:
            # Frames come back pipelined: frame i is written while frame i+1 renders.
            for i, frame in zip(indices, renderer.render_sequence(rigs, eyes=job.eyes, view=job.view,
                                                                  aux=job.render_aux, spp=job.spp,
                                                                  progress=bar.update if bar else None)):
                check_interrupt()
                write_frame(job, i, frame, files)
                done += 1
                timings.append(frame.timings)
                unavailable.update(frame.timings_unavailable)
                ran.update(dict.fromkeys(frame.passes))
                if on_frame is not None:
                    on_frame(i)
                check_interrupt()
    except KeyboardInterrupt:
        # Every file is written atomically, so what is there is whole: say what was kept.
        raise CaptureInterrupted(f"interrupted after {done} of {len(indices)} frame(s); "
                                 f"the {len(files)} file(s) written are kept in {job.out_dir}/") from None
    finally:
        if bar is not None:
            bar.close()
    return summarize(job, renderer.gl.info()["renderer"], not renderer.gl.is_software, files, timings, ran,
                     unavailable, written=len(indices), skipped=len(skipped),
                     denoise=list(renderer.plan().denoise) if renderer.settings.denoise else [],
                     stereo=renderer.settings.stereo,
                     stereo_counts=renderer.stereo_counts())  # the last frame's reused pixels or holes


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
    p = job.out_dir / f"{job.prefix}_timings.json"
    atomic_write_bytes(p, json.dumps(summary, indent=1).encode())
    return p
