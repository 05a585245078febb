import errno
import os
import stat
import tempfile

import numpy as np
import pytest

from conftest import fail_writes
from rayvr.util.output import (MAX_PREFIX_BYTES, OutputError, atomic_write_bytes, check_file_prefix, check_output_dir,
                          make_output_dir, write_npy, write_png)


@pytest.fixture
def umask():
    """Set the process umask for one test, restore it after."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664), (0o000, 0o666)])
def test_output_files_get_the_umask_like_a_plain_open(tmp_path, umask, mask, mode):
    umask(mask)
    atomic_write_bytes(tmp_path / "a.json", b"{}")
    write_png(tmp_path / "a.png", np.zeros((2, 3, 3), np.uint8))
    write_npy(tmp_path / "a.npy", np.zeros(3, np.float32))
    with open(tmp_path / "plain.txt", "w"):
        pass
    assert stat.S_IMODE(os.stat(tmp_path / "plain.txt").st_mode) == mode
    for name in ("a.json", "a.png", "a.npy"):
        assert stat.S_IMODE(os.stat(tmp_path / name).st_mode) == mode, name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "a.npy", "a.png", "plain.txt"]  # no temp left


def test_replacing_keeps_no_temp_and_a_failed_write_leaves_the_old_file(tmp_path, monkeypatch):
    p = tmp_path / "f.bin"
    atomic_write_bytes(p, b"one")
    atomic_write_bytes(p, b"two")
    assert p.read_bytes() == b"two" and [x.name for x in tmp_path.iterdir()] == ["f.bin"]

    def fail(*a):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError):
        atomic_write_bytes(p, b"three")
    assert p.read_bytes() == b"two" and [x.name for x in tmp_path.iterdir()] == ["f.bin"]


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EFBIG, errno.EIO])
def test_a_failed_write_is_one_output_error_naming_the_file(tmp_path, monkeypatch, code):
    """Disk full (ENOSPC), a file too large (EFBIG), an I/O error: one line the CLI prints."""
    fail_writes(monkeypatch, code)
    p = tmp_path / "frame.png"
    with pytest.raises(OutputError) as err:
        write_png(p, np.zeros((2, 3, 3), np.uint8))
    assert str(err.value) == f"{p}: cannot write: {os.strerror(code)}" and err.value.errno == code
    assert list(tmp_path.iterdir()) == []  # no temporary file, no partial file


@pytest.mark.parametrize("prefix", ["../X", "a/b", "a\\b", "", ".", "..", ".hidden", "a\0b",
                                    "x" * (MAX_PREFIX_BYTES + 1), "\u00e9" * (MAX_PREFIX_BYTES // 2 + 1)])
def test_file_prefix_must_be_a_plain_name(prefix):
    with pytest.raises(ValueError, match="file prefix must be a plain name"):
        check_file_prefix(prefix)


@pytest.mark.parametrize("prefix", ["frame", "shot-01", "a..b", "x" * MAX_PREFIX_BYTES, "caf\u00e9 2"])
def test_plain_prefixes_pass(prefix):
    assert check_file_prefix(prefix) == prefix


def test_capture_job_refuses_a_prefix_outside_its_folder():
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.app.capture import CaptureJob

    rig = StereoRig()
    with pytest.raises(ValueError, match="file prefix"):
        CaptureJob(rig, [rig.pose], prefix="../escape")
    with pytest.raises(ValueError, match="file prefix"):
        CaptureJob(rig, [rig.pose], prefix="nul\0byte")


def test_output_folder_is_checked_without_being_made(tmp_path, monkeypatch):
    out = tmp_path / "a" / "b"
    assert check_output_dir(out) == out
    assert list(tmp_path.iterdir()) == []  # checked, nothing created
    assert make_output_dir(out).is_dir()
    check_output_dir(out)  # an existing folder passes too
    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match=r"cannot create output folder: .*/f is not a folder"):
        check_output_dir(tmp_path / "f" / "sub")
    with pytest.raises(OutputError, match="exists and is not a folder"):
        check_output_dir(tmp_path / "f")

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "TemporaryFile", refuse)  # what a read-only parent does, even for root
    with pytest.raises(OutputError, match=rf"{tmp_path}/new: cannot create output folder: {tmp_path} is not "
                                          r"writable: Permission denied"):
        check_output_dir(tmp_path / "new")
    with pytest.raises(OutputError, match="output folder is not writable: Permission denied"):
        check_output_dir(out)
    assert not (tmp_path / "new").exists()
