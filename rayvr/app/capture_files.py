"""Where a capture job (app/capture.py CaptureJob) writes each file of a frame: the names the capture
writes and the transforms.json of a multi-view capture (app/views.py) points at."""
from __future__ import annotations

from pathlib import Path

from ..frame.readback import INTEGER_AUX


def file_name(job, index: int, eye: str, kind: str, ext: str) -> Path:
    """The file of one eye image of frame `index`: `kind` (color, camera, an aux channel) and `ext`."""
    frame = f"_{index:04d}" if len(job.poses) > 1 else ""
    suffix = "" if kind == "color" else f"_{kind}"
    return job.out_dir / f"{job.prefix}{frame}_{eye}{suffix}.{ext}"


def color_file(job, index: int, eye: str) -> Path:
    """Where an eye's colour (or debug view) image goes: PNG, or NPY with format npy (raw uint8 RGB)."""
    kind = "color" if job.view == "color" else job.view
    return file_name(job, index, eye, kind, "npy" if job.format == "npy" else "png")


def aux_file(job, index: int, eye: str, name: str) -> Path:
    """Where aux channel `name` of an eye goes: NPY, or EXR for float channels with format exr
    (integer IDs stay exact in NPY); the HDR colour of an EXR job is the colour's EXR twin."""
    if name == "hdr" and job.hdr_exr:
        return file_name(job, index, eye, "color", "exr")
    exr = job.format == "exr" and name not in INTEGER_AUX
    return file_name(job, index, eye, name, "exr" if exr else "npy")


def flow_file(job, index: int, eye: str, direction: str, mask: bool = False) -> Path:
    """Where frame `index`'s flow to the next ("forward") or previous ("backward") frame goes (app/flow.py):
    float (dx, dy) as EXR with format exr, else NPY; with `mask`, its validity mask (bool NPY)."""
    if mask:
        return file_name(job, index, eye, f"flow_{direction}_valid", "npy")
    return file_name(job, index, eye, f"flow_{direction}", "exr" if job.format == "exr" else "npy")
