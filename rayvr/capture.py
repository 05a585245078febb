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

from .camera import Pose, StereoRig, load_path, orbit
from .output import (FORMATS, atomic_write_bytes, check_file_prefix, check_output_dir, make_output_dir,
                     openexr, write_exr, write_npy, write_png)
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

    def __post_init__(self):
        check_file_prefix(self.prefix)  # every file stays inside out_dir
        if not (isinstance(self.spp, int) and self.spp >= 1):
            raise ValueError(f"spp must be a positive whole number, got {self.spp!r}")
        if self.format not in FORMATS:
            raise ValueError(f"unknown output format {self.format!r}; allowed: {', '.join(FORMATS)}")
        if self.format == "exr":
            openexr()  # a missing package is one clear error before any rendering

    @property
    def hdr_exr(self) -> bool:
        """Whether the linear HDR colour goes to <prefix>_<eye>.exr (format exr, colour view)."""
        return self.format == "exr" and self.view == "color"

    @property
    def render_aux(self) -> tuple:
        """The aux channels to read back: the user's, plus the HDR colour for its EXR."""
        return self.aux + ("hdr",) if self.hdr_exr and "hdr" not in self.aux else self.aux


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


def write_frame(job: CaptureJob, index: int, frame: Frame, written: list[Path]) -> None:
    """Write one frame's files, appending each to `written` as soon as it is whole."""
    make_output_dir(job.out_dir)  # only now: a run that fails before leaves no empty folder
    for eye, img in frame.eyes.items():
        p = file_name(job, index, eye, "color" if job.view == "color" else job.view, "png")
        write_png(p, img.color)
        written.append(p)
        for name, arr in img.aux.items():
            if name == "hdr" and job.hdr_exr:  # the colour's linear twin, not an aux file
                p = file_name(job, index, eye, "color", "exr")
            elif job.format == "exr" and arr.dtype.kind == "f":  # integer IDs stay exact in NPY
                p = file_name(job, index, eye, name, "exr")
            else:
                p = file_name(job, index, eye, name, "npy")
                write_npy(p, arr)
                written.append(p)
                continue
            write_exr(p, arr, EXR_CHANNELS[1 if arr.ndim == 2 else arr.shape[-1]])
            written.append(p)


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


def run_capture(renderer: Renderer, job: CaptureJob, progress: bool = True) -> dict:
    """Render every pose of `job`, write the files, return a summary (files, GPU ms per pass)."""
    check_output_dir(job.out_dir)
    files, timings, unavailable, ran = [], [], set(), {}
    bar = None
    if progress and len(job.poses) * job.spp > 1:
        from tqdm import tqdm

        # with --spp the bar counts samples: one frame of many samples is long work too
        bar = tqdm(total=len(job.poses) * job.spp, unit="sample" if job.spp > 1 else "frame", desc="capture")
    rigs = [StereoRig(**{**job.rig.__dict__, "pose": pose}) for pose in job.poses]
    done = 0
    try:
        with interrupts_between_frames() as check_interrupt:
            # Frames come back pipelined: frame i is written while frame i+1 renders.
            for i, frame in enumerate(renderer.render_sequence(rigs, eyes=job.eyes, view=job.view,
                                                               aux=job.render_aux, spp=job.spp,
                                                               progress=bar.update if bar else None)):
                check_interrupt()
                write_frame(job, i, frame, files)
                done += 1
                timings.append(frame.timings)
                unavailable.update(frame.timings_unavailable)
                ran.update(dict.fromkeys(frame.passes))
                check_interrupt()
    except KeyboardInterrupt:
        # Every file is written atomically, so what is there is whole: say what was kept.
        raise CaptureInterrupted(f"interrupted after {done} of {len(job.poses)} frame(s); "
                                 f"the {len(files)} file(s) written are kept in {job.out_dir}/") from None
    finally:
        if bar is not None:
            bar.close()
    passes = sorted({k for t in timings for k in t})
    mean = {k: float(np.mean([t[k] for t in timings if k in t])) for k in passes}
    summary = {"frames": len(job.poses), "files": [str(f) for f in files], "gpu_ms_mean": mean,
               "gpu_ms_per_frame": timings, "gl": renderer.gl.info()["renderer"],
               "timings_meaningful": not renderer.gl.is_software,
               "passes": list(ran), "gpu_ms_unavailable": sorted(unavailable),  # timers that read back garbage
               "size": list(job.rig.size), "eyes": job.eyes, "spp": job.spp,
               "denoise": list(renderer.plan().denoise) if renderer.settings.denoise else [],
               "gpu_ms_note": "per sample (the last of each frame's samples)" if job.spp > 1 else "per frame",
               "stereo": renderer.settings.stereo,
               "stereo_counts": renderer.stereo_counts()}  # the last frame's reused pixels or holes
    return summary


def write_summary(job: CaptureJob, summary: dict) -> Path:
    p = job.out_dir / f"{job.prefix}_timings.json"
    atomic_write_bytes(p, json.dumps(summary, indent=1).encode())
    return p
