"""The capture pipeline (rayvr/app/writers.py): frames encoded and written on a bounded pool of
threads are byte for byte what the serial path (--writers 1) writes, no more frames than the
queue's bound are held in memory however slow the writer, every PNG level is lossless, a writer
thread's failure is one line naming the file with nothing half-written, and an interrupted run
resumes to whole frames."""
import errno
import importlib.util
import hashlib
import json
import re
import resource
import subprocess
import sys
import threading
import time
import weakref

import numpy as np
import pytest
from PIL import Image

from conftest import fail_writes, interrupt_rayvr, run_rayvr
from rayvr.cli import main

SIZE = "32x24"
BOOKKEEPING = ("frame_timings.json", ".rayvr-lock")  # the timings differ run to run; the lock is gone


def capture(out, *extra, frames=6):
    """`rayvr capture` of an orbit in this process; its exit status."""
    return main(["capture", "--frames", str(frames), "--size", SIZE, "--out", str(out), "-q", *extra])


def files(out) -> dict:
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.name not in BOOKKEEPING}


def summary(out) -> dict:
    return json.loads((out / "frame_timings.json").read_text())


def one_line(err: str) -> str:
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def temporary_files(out) -> list:
    return [p.name for p in out.iterdir() if p.name.endswith(".tmp")]


def verified(out) -> set:
    """The frames whose records are all whole: each names the folder's job and both eyes' PNGs,
    with their checksums (every record on disk must be)."""
    from rayvr.app.capture import identity_digest

    digest = identity_digest(json.loads((out / "frame_job.json").read_text()))
    done = set()
    for p in out.glob("frame_*_record.json"):
        record = json.loads(p.read_text())
        assert record["job"] == digest and len(record["files"]) == 2, p
        for name, want in record["files"].items():
            assert hashlib.sha256((out / name).read_bytes()).hexdigest() == want["sha256"], name
        done.add(record["frame"])
    return done


# ------------------------------------------------------------------ the pool writes the serial path's bytes

NO_EXR = pytest.mark.skipif(importlib.util.find_spec("OpenEXR") is None,
                            reason="EXR output needs the optional OpenEXR (pip install 'rayvr[exr]')")


@pytest.mark.parametrize("fmt", ["png", "npy", pytest.param("exr", marks=NO_EXR)])
def test_a_pooled_capture_writes_the_bytes_of_the_serial_one(tmp_path, fmt):
    aux = ["--aux", "depth,normal,material"]
    serial, pooled = tmp_path / "serial", tmp_path / "pooled"
    assert capture(serial, "--format", fmt, "--writers", "1", *aux) == 0
    assert capture(pooled, "--format", fmt, "--writers", "3", *aux) == 0
    assert files(pooled) == files(serial)  # every image, aux array, record and the job file
    assert len(files(serial)) == 6 * (2 * 4 + (2 if fmt == "exr" else 0) + 1) + 1
    s, p = summary(serial), summary(pooled)
    assert p["files"] == [f.replace(str(serial), str(pooled)) for f in s["files"]]  # in frame order
    assert (s["pipeline"]["writers"], p["pipeline"]["writers"]) == (1, 3)


def test_npy_colour_holds_the_pixels_of_the_png(tmp_path):
    assert capture(tmp_path / "png", frames=2) == 0
    assert capture(tmp_path / "npy", "--format", "npy", frames=2) == 0
    for i in range(2):
        for eye in ("left", "right"):
            raw = np.load(tmp_path / "npy" / f"frame_{i:04d}_{eye}.npy")
            png = np.asarray(Image.open(tmp_path / "png" / f"frame_{i:04d}_{eye}.png"))
            assert raw.dtype == np.uint8 and raw.shape == (24, 32, 3)
            assert np.array_equal(raw, png)
    assert not list((tmp_path / "npy").glob("*.png"))


def test_npy_colour_with_views_is_one_line(tmp_path, capsys):
    assert main(["capture", "--views", "sphere:2", "--format", "npy", "--out", str(tmp_path / "o"), "-q"]) == 2
    assert "--views writes a transforms.json" in one_line(capsys.readouterr().err)


# ------------------------------------------------------------------ memory: a bounded queue

@pytest.mark.parametrize("writers", [1, 3])
def test_a_slow_writer_holds_no_more_frames_than_the_queue_bound(gl, tmp_path, monkeypatch, writers):
    """100 tiny frames through writers held back until the queue is full: the frames alive at once
    (each counted from the renderer handing it over until it is freed) never pass the bound, and
    the queue does fill up to it: rendering waited for the writers. The writers wait for that (a
    gate, not a sleep: three writers slowed to 3 ms, then to 15 ms a PNG, still kept up with the
    renderer on a loaded 2-core CI host, and the queue never filled)."""
    from rayvr.app import capture as capture_mod
    from rayvr.app.capture import CaptureJob, poses_for, run_capture
    from rayvr.app.writers import QUEUED_PER_POOL
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import Renderer

    live, most, lock = [0], [0], threading.Lock()
    bound = 1 if writers == 1 else writers + QUEUED_PER_POOL
    full = threading.Event()  # set once `bound` frames are alive: the writers may go on

    def freed():
        with lock:
            live[0] -= 1

    def track(frame):
        with lock:
            live[0] += 1
            most[0] = max(most[0], live[0])
            if most[0] >= bound:
                full.set()
        weakref.finalize(frame, freed)
        return frame

    real_sequence, real_png = Renderer.render_sequence, capture_mod.write_png

    def counted_sequence(self, *args, **kw):
        yield from map(track, real_sequence(self, *args, **kw))  # holds no frame itself

    def slow_png(*args, **kw):
        full.wait(timeout=60)  # the queue fills while the first frames' writers wait here
        return real_png(*args, **kw)

    monkeypatch.setattr(Renderer, "render_sequence", counted_sequence)
    monkeypatch.setattr(capture_mod, "write_png", slow_png)
    with Renderer(gl=gl) as r:
        rig = StereoRig.for_scene(r.scene, size=(8, 8))
        job = CaptureJob(rig, poses_for(rig, r.scene, frames=100), out_dir=tmp_path / "o", writers=writers)
        result = run_capture(r, job, progress=False)
    assert full.is_set() and most[0] == bound and live[0] == 0
    assert result["written"] == 100 and len(result["files"]) == 200
    assert result["pipeline"]["peak_in_flight"] == bound and result["pipeline"]["queue_limit"] >= bound
    assert result["pipeline"]["ms_per_frame"]["write_wait"] > 0


def test_the_writer_keeps_frames_in_order_and_raises_the_first_failure():
    from rayvr.app.writers import FrameWriter

    done, order = [], []

    def task(i, delay, fail=False):
        def run():
            time.sleep(delay)
            order.append(i)
            if fail:
                raise OSError(f"frame {i} failed")
            return i * 10
        return run

    with FrameWriter(3, limit=3) as writer:
        for i, delay in enumerate([0.05, 0.0, 0.02, 0.0]):
            done += writer.submit(i, task(i, delay))
            assert writer.in_flight() < 3
        done += writer.finish()
    assert done == [(0, 0), (1, 10), (2, 20), (3, 30)] and order[0] != 0  # finished out of order, handed back in order
    with pytest.raises(OSError, match="frame 1 failed"):
        with FrameWriter(2) as writer:
            writer.submit(0, task(0, 0.02))
            writer.submit(1, task(1, 0.0, fail=True))
            writer.submit(2, task(2, 0.0, fail=True))
            writer.finish()


def test_the_progress_bar_says_where_the_time_goes(tmp_path, capsys):
    assert main(["capture", "--frames", "3", "--size", SIZE, "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    # tqdm writes the rate as s/frame when a frame takes over a second (a first frame that compiles
    # shaders, a loaded machine): either form
    assert re.search(r"3/3 \[[^]]*(frame/s|s/frame), GPU (n/a|[\d.]+), render \d+, read-back \d+, write wait \d+ ms/frame\]", err), err


# ------------------------------------------------------------------ PNG compression

def test_every_png_compression_level_is_lossless(tmp_path):
    sizes, pixels = {}, {}
    for level in (0, 1, 6, 9):
        out = tmp_path / f"level{level}"
        assert main(["capture", "--size", "64x48", "--eye", "left", "--png-compression", str(level),
                     "--out", str(out), "-q"]) == 0
        png = out / "frame_left.png"
        sizes[level], pixels[level] = png.stat().st_size, np.asarray(Image.open(png))
    for level in (0, 1, 9):
        assert np.array_equal(pixels[level], pixels[6])
    assert sizes[0] > 64 * 48 * 3 > sizes[1] and sizes[0] > sizes[9]  # 0 stores the pixels; the others compress


def test_the_default_png_level_is_the_documented_one(tmp_path):
    from rayvr.app.writers import DEFAULT_PNG_COMPRESSION

    assert capture(tmp_path / "default", frames=2) == 0
    assert capture(tmp_path / "given", "--png-compression", str(DEFAULT_PNG_COMPRESSION), frames=2) == 0
    assert capture(tmp_path / "six", "--png-compression", "6", frames=2) == 0
    assert files(tmp_path / "default") == files(tmp_path / "given") != files(tmp_path / "six")
    assert summary(tmp_path / "default")["pipeline"]["png_compression"] == DEFAULT_PNG_COMPRESSION


@pytest.mark.parametrize("flag, value, allowed", [("--png-compression", "10", "0 to 9"),
                                                  ("--png-compression", "-1", "0 to 9"),
                                                  ("--png-compression", "fast", "0 to 9"),
                                                  ("--png-compression", "1.5", "0 to 9"),
                                                  ("--writers", "0", "1 to 256")])
def test_a_bad_pipeline_flag_is_one_line(tmp_path, capsys, flag, value, allowed):
    with pytest.raises(SystemExit) as exit_:
        main(["capture", flag, value, "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert one_line(capsys.readouterr().err).startswith(
        f"rayvr capture: error: argument {flag}: expected a whole number from {allowed}, got ")
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ failures on a writer thread

def test_an_unwritable_file_on_a_writer_thread_is_one_line_and_the_rest_resumes(tmp_path, capsys, monkeypatch):
    out = tmp_path / "o"
    fail_writes(monkeypatch, errno.EACCES, "frame_0003_")
    assert capture(out, "--writers", "3") == 2
    err = one_line(capsys.readouterr().err)
    assert err in {f"rayvr capture: error: {out}/frame_0003_{eye}.png: cannot write: Permission denied\n"
                   for eye in ("left", "right")}
    assert temporary_files(out) == []  # nothing half-written
    done = verified(out)
    assert 3 not in done and {0, 1, 2} <= done  # frames before it were finished; those behind it may be
    monkeypatch.undo()
    assert capture(out, "--writers", "3") == 0
    assert (summary(out)["written"], summary(out)["skipped"]) == (6 - len(done), len(done))
    assert capture(tmp_path / "reference", "--writers", "1") == 0
    assert files(out) == files(tmp_path / "reference")


def test_a_real_write_error_on_a_writer_thread_is_one_line_and_leaves_no_folder(tmp_path):
    """The child's file size limit (RLIMIT_FSIZE) fails the first PNG with EFBIG, as a full disk
    fails with ENOSPC; the job file (smaller) was written, and goes again with the folder."""
    out = tmp_path / "new" / "o"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (3000, 3000))  # a 96x72 PNG is larger, the job file not

    run = subprocess.run([sys.executable, "-m", "rayvr", "capture", "--frames", "3", "--size", "96x72",
                          "--writers", "2", "--out", str(out), "-q"],
                         capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert run.returncode == 2
    assert one_line(run.stderr) == f"rayvr capture: error: {out}/frame_0000_left.png: cannot write: File too large\n"
    assert list(tmp_path.iterdir()) == []  # no folder, no temporary file


# ------------------------------------------------------------------ interrupted, then resumed

def test_an_interrupted_pooled_capture_resumes_to_whole_frames(tmp_path):
    out, frames = tmp_path / "o", 400
    args = ["capture", "--frames", frames, "--size", "24x16", "--writers", "3", "--materials", "raster.toml",
            "--out", out, "-q"]  # raster: the quickest frames
    code, _, err = interrupt_rayvr(args, lambda: out.is_dir() and len(list(out.glob("frame_*_record.json"))) >= 5,
                                   "the capture wrote no frame")
    assert code == 130, err
    done = verified(out)
    assert 5 <= len(done) < frames and temporary_files(out) == []
    # what it says it kept is what is on disk
    assert one_line(err) == (f"rayvr capture: interrupted after {len(done)} of {frames} frame(s); the "
                             f"{2 * len(done)} file(s) written are kept in {out}/\n")
    again = run_rayvr(*args)
    assert again.returncode == 0, again.stderr
    assert (summary(out)["written"], summary(out)["skipped"]) == (frames - len(done), len(done))
    reference = tmp_path / "reference"
    assert run_rayvr(*args[:-3], "--writers", "1", "--out", reference, "-q").returncode == 0
    assert files(out) == files(reference)


def test_workers_on_this_host_share_its_writer_threads(monkeypatch):
    """Ray workers all on this host (no --address) split the host's default writers between them;
    a count given, or workers on other hosts, keep theirs."""
    from rayvr.app import writers

    monkeypatch.setattr(writers, "default_writers", lambda: 16)
    assert writers.writers_per_worker(None, 4, local=True) == 4
    assert writers.writers_per_worker(None, 32, local=True) == 1
    assert writers.writers_per_worker(3, 4, local=True) == 3
    assert writers.writers_per_worker(None, 4, local=False) is None
