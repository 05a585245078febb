"""What a capture keeps in its output folder (rayvr/app/capture.py JobFolder): resume skips only the
frames whose records verify, one job writes into a folder at a time, a folder holding another
job's frames is refused, and an output that cannot be written is one line before the work with
nothing half-made left behind."""
import errno
import json
import logging
import resource
import shutil
import signal
import subprocess
import sys
import time

import pytest

from conftest import fail_writes, run_rayvr
from rayvr.cli import main

SIZE = "24x16"


def capture(out, *extra, frames=3):
    """`rayvr capture` of a 3-frame orbit in this process; its exit status."""
    return main(["capture", "--frames", str(frames), "--size", SIZE, "--out", str(out), "-q", *extra])


def pngs(out):
    return {p.name: p.read_bytes() for p in sorted(out.glob("frame_*.png"))}


def counts(out):
    summary = json.loads((out / "frame_timings.json").read_text())
    return summary["written"], summary["skipped"]


def one_line(err: str) -> str:
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


# ------------------------------------------------------------------ resume verifies what it skips

@pytest.mark.parametrize("damage", ["cut to 10 bytes", "one byte changed"])
def test_resume_renders_a_damaged_frame_again(tmp_path, caplog, damage):
    out = tmp_path / "o"
    assert capture(out) == 0
    good = pngs(out)
    victim = out / "frame_0001_left.png"
    data = bytearray(victim.read_bytes())
    if damage == "cut to 10 bytes":
        del data[10:]
    else:  # the same size: only the checksum can tell
        data[len(data) // 2] ^= 0xFF
    victim.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING, logger="rayvr"):
        assert capture(out) == 0
    assert pngs(out) == good  # frame 1 rendered again, byte for byte what it was
    assert counts(out) == (1, 2)
    assert "1 frame(s) on disk are not verified" in caplog.text and "frame_0001_left.png" in caplog.text


def test_a_rerun_does_not_keep_another_jobs_frames(tmp_path):
    """The issue's case: frames of job B (--spp 2 --exposure 4) in job A's folder, as two jobs run
    into one folder at once left them; a rerun of A skipped them."""
    a, b = tmp_path / "a", tmp_path / "b"
    assert capture(a) == 0 and capture(b, "--spp", "2", "--exposure", "4") == 0
    good = pngs(a)
    for p in b.glob("frame_0001_*"):  # B's frame 1, its record too
        shutil.copy(p, a / p.name)
    assert pngs(a) != good
    assert capture(a) == 0
    assert pngs(a) == good and counts(a) == (1, 2)


def test_frames_without_records_are_rendered_again(tmp_path, caplog):
    """Frames an older rayvr wrote have no record: they are redone, not decode-checked (a file
    that decodes may still be another job's)."""
    out = tmp_path / "o"
    assert capture(out) == 0
    good = pngs(out)
    for p in out.glob("frame_*_record.json"):
        p.unlink()
    (out / "frame_0002_left.png").write_bytes(b"\x89PNG\r\n\x1a\n")  # one cut short, which was then kept
    with caplog.at_level(logging.WARNING, logger="rayvr"):
        assert capture(out) == 0
    assert counts(out) == (3, 0) and pngs(out) == good
    assert "3 frame(s) on disk are not verified" in caplog.text and "no record" in caplog.text


# ------------------------------------------------------------------ one job per folder

def test_a_second_job_into_a_folder_in_use_is_refused(tmp_path):
    """Job B runs; job A (other settings) and B's twin (the same command) into its folder are
    refused, in one line naming the folder; once B is gone, A is refused as another job."""
    out = tmp_path / "o"
    job_b = ["capture", "--frames", "2000", "--size", SIZE, "--spp", "32", "--exposure", "4", "--out", str(out), "-q"]
    job_a = ["capture", "--frames", "2000", "--size", SIZE, "--out", str(out), "-q"]
    proc = subprocess.Popen([sys.executable, "-m", "rayvr", *job_b], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + 120
        while not (out.is_dir() and any(p.suffix == ".png" for p in out.iterdir())):
            assert proc.poll() is None and time.monotonic() < deadline, "job B wrote no frame"
            time.sleep(0.02)
        a, twin = run_rayvr(*job_a, timeout=60), run_rayvr(*job_b, timeout=60)  # each refused at once
        b_ran_throughout = proc.poll() is None
        proc.send_signal(signal.SIGINT)
        _, b_err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert b_ran_throughout and proc.returncode == 130, b_err
    for run in (a, twin):
        assert run.returncode == 2
        assert one_line(run.stderr).startswith(f"rayvr capture: error: {out}: output folder is busy: another "
                                               f"capture (pid {proc.pid} on ")
    assert a.stderr.endswith("use another --out (frame_job.json -> this job: spp 32 -> 1, "
                             "settings.exposure 4.0 -> 1.0)\n")  # what differs
    assert twin.stderr.endswith("wait for it to end or use another --out\n")  # the same job, still busy
    assert not (out / ".rayvr-lock").exists()  # B removed its lock file as it ended
    again = run_rayvr(*job_a)
    assert again.returncode == 2
    assert f"{out}: holds frames of another job" in one_line(again.stderr)
    assert "spp 32 -> 1" in again.stderr and "settings.exposure 4.0 -> 1.0" in again.stderr


def test_a_rerun_with_other_settings_is_refused_and_changes_nothing(tmp_path, capsys):
    out = tmp_path / "o"
    assert capture(out) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    assert capture(out, "--spp", "2", "--exposure", "4") == 2
    err = one_line(capsys.readouterr().err)
    assert f"{out}: holds frames of another job (frame_job.json -> this job: spp 1 -> 2, " \
           "settings.exposure 1.0 -> 4.0); use another --out or --prefix" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert capture(out, "--prefix", "bright", "--spp", "2", "--exposure", "4") == 0  # another prefix: its own job
    assert counts(out) == (3, 0) and capture(out) == 0 and counts(out) == (0, 3)



def test_overwrite_replaces_another_jobs_frames_and_leaves_none_of_them(tmp_path):
    """--overwrite: the frames another job left (more of them than this job has, too) are gone and
    every frame is this job's, verified on the next rerun."""
    out = tmp_path / "o"
    assert capture(out, "--exposure", "4", frames=4) == 0
    bright = pngs(out)
    assert capture(out, "--overwrite") == 0 and counts(out) == (3, 0)
    mine = pngs(out)
    assert set(mine) == {f"frame_{i:04d}_{eye}.png" for i in range(3) for eye in ("left", "right")}  # no 4th frame
    assert all(mine[name] != bright[name] for name in mine)
    assert not list(out.glob("frame_0003_*"))
    assert capture(out) == 0 and counts(out) == (0, 3)  # this job's now: the plain rerun resumes it

def test_a_killed_job_leaves_no_stale_lock(tmp_path):
    out = tmp_path / "o"
    hold = ("import sys, time; from pathlib import Path; from rayvr.app.capture import lock_folder; "
            "Path(sys.argv[1]).mkdir(); lock_folder(Path(sys.argv[1])); print('locked', flush=True); time.sleep(600)")
    holder = subprocess.Popen([sys.executable, "-c", hold, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "locked\n"
        assert capture(out) == 2  # held
        holder.send_signal(signal.SIGKILL)  # a crash: no cleanup ran
        holder.wait(timeout=30)
    finally:
        holder.kill()
    assert (out / ".rayvr-lock").exists()  # the file stays, the lock does not
    assert capture(out) == 0 and counts(out) == (3, 0)
    assert not (out / ".rayvr-lock").exists()


# ------------------------------------------------------------------ outputs that cannot be written

@pytest.mark.parametrize("taken", ["frame_0001_right.png", "frame_timings.json", "frame_job.json",
                                   "frame_0002_record.json"])
def test_an_output_name_taken_by_a_folder_is_one_line_before_any_work(tmp_path, capsys, monkeypatch, taken):
    out = tmp_path / "o"
    (out / taken).mkdir(parents=True)
    rendered = []
    monkeypatch.setattr("rayvr.renderer.Renderer.render_sequence", lambda *a, **k: rendered.append(1) or iter(()))
    assert capture(out) == 2
    assert one_line(capsys.readouterr().err) == (f"rayvr capture: error: {out / taken}: an output file's name is "
                                                 f"taken by a folder\n")
    assert not rendered and sorted(p.name for p in out.iterdir()) == [taken]  # nothing rendered or written


def test_a_full_disk_on_the_first_file_is_one_line_and_leaves_no_folder(tmp_path):
    """A real write error: the child's file size limit (RLIMIT_FSIZE) makes the first PNG fail
    with EFBIG, as a full disk fails with ENOSPC."""
    out = tmp_path / "new" / "o"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))  # the 64x48 PNG is larger

    run = subprocess.run([sys.executable, "-m", "rayvr", "capture", "--size", "64x48", "--out", str(out), "-q"],
                         capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert run.returncode == 2
    assert one_line(run.stderr) == f"rayvr capture: error: {out}/frame_left.png: cannot write: File too large\n"
    assert list(tmp_path.iterdir()) == []  # no folder, no temporary file


def test_a_full_disk_mid_sequence_keeps_the_whole_frames_and_resumes(tmp_path, capsys, monkeypatch):
    out = tmp_path / "o"
    fail_writes(monkeypatch, errno.ENOSPC, "frame_0001_right.png")
    assert capture(out, "--writers", "1") == 2  # frames written in turn: the one after the failure is not begun
    assert one_line(capsys.readouterr().err) == (f"rayvr capture: error: {out}/frame_0001_right.png: cannot write: "
                                                 f"No space left on device\n")
    assert sorted(p.name for p in out.iterdir()) == ["frame_0000_left.png", "frame_0000_record.json",
                                                     "frame_0000_right.png", "frame_0001_left.png", "frame_job.json"]
    monkeypatch.undo()  # space again
    assert capture(out) == 0 and counts(out) == (2, 1)


def test_a_shipped_config_is_known_by_name_and_content_not_by_where_the_checkout_lies(tmp_path):
    """The built-in room's default config (and any config rayvr ships) enters a capture job's
    identity by name and content: a capture resumes in another clone of the same rayvr. A user's
    own file keeps its path, size and mtime."""
    import hashlib
    import shutil

    from rayvr.commands.capture import file_identity
    from rayvr.scene.loader import ASSETS_DIR

    shipped = ASSETS_DIR / "default_room.toml"
    assert file_identity(shipped) == {"shipped": "default_room.toml",
                                      "sha256": hashlib.sha256(shipped.read_bytes()).hexdigest()}
    own = tmp_path / "default_room.toml"
    shutil.copy(shipped, own)
    ident = file_identity(own)
    assert ident["path"] == str(own.resolve()) and {"bytes", "mtime_ns"} <= set(ident)


def test_a_resume_with_every_frame_written_says_there_was_nothing_to_write(tmp_path, capsys):
    """Not "wrote 0 files" (issue 46 item 9): the folder holds every frame already."""
    out = tmp_path / "o"
    assert capture(out) == 0
    capsys.readouterr()
    assert main(["capture", "--frames", "3", "--size", SIZE, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert f"nothing to write: {out}/ holds all 3 frame(s) (both eye(s)) already" in said and "wrote 0" not in said
    assert "frames: 0 written, 3 skipped" in said

