"""--format exr: the linear HDR colour and the float aux channels as OpenEXR (the optional
`OpenEXR` package, rayvr[exr]); integer channels stay NPY; files written atomically."""
import os
import stat
import sys

import numpy as np
import pytest

from conftest import run_rayvr
from rayvr import cli
from rayvr.frame.cameras.rig import StereoRig
from rayvr.util.output import OutputError, write_exr


def read_exr(path):
    """{channel: float32 array} of an EXR file, one array per channel."""
    OpenEXR = pytest.importorskip("OpenEXR")
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.array(ch.pixels) for name, ch in f.channels().items()}


def rgb(channels):
    return np.stack([channels["R"], channels["G"], channels["B"]], axis=-1)


def test_exr_capture_round_trips_hdr_and_float_aux(gl, tmp_path):
    pytest.importorskip("OpenEXR")
    from rayvr import Renderer
    from rayvr.app.capture import CaptureJob, run_capture

    aux = ("depth", "normal", "position", "albedo", "zbuffer", "material", "triangle")
    with Renderer(gl=gl) as r:
        rig = StereoRig.for_scene(r.scene, size=(40, 30))
        reference = r.render(rig, aux=aux + ("hdr",))  # what the files must hold
        job = CaptureJob(rig, [rig.pose], aux=aux, out_dir=tmp_path / "o", format="exr")
        summary = run_capture(r, job, progress=False)
    names = sorted(os.listdir(tmp_path / "o"))
    for eye in ("left", "right"):
        assert f"frame_{eye}.png" in names and f"frame_{eye}.exr" in names
        ref = reference.eyes[eye].aux
        hdr = rgb(read_exr(tmp_path / "o" / f"frame_{eye}.exr"))
        assert hdr.dtype == np.float32 and hdr.max() > 0.1
        np.testing.assert_array_equal(hdr, ref["hdr"])  # float32 in, float32 out
        for name in ("normal", "position", "albedo"):
            back = rgb(read_exr(tmp_path / "o" / f"frame_{eye}_{name}.exr"))
            np.testing.assert_array_equal(back, ref[name].astype(np.float32))  # position: float64 -> 32
        for name in ("depth", "zbuffer"):
            np.testing.assert_array_equal(read_exr(tmp_path / "o" / f"frame_{eye}_{name}.exr")["Z"], ref[name])
        for name in ("material", "triangle"):  # integer IDs stay exact
            np.testing.assert_array_equal(np.load(tmp_path / "o" / f"frame_{eye}_{name}.npy"), ref[name])
        assert f"frame_{eye}_hdr.exr" not in names and f"frame_{eye}_depth.npy" not in names
    assert len(summary["files"]) == len(names) and not [n for n in names if n.endswith(".tmp")]


def test_write_exr_is_atomic_and_gets_the_umask(tmp_path, monkeypatch):
    OpenEXR = pytest.importorskip("OpenEXR")
    old = os.umask(0o027)
    try:
        write_exr(tmp_path / "a.exr", np.ones((2, 3), np.float32), "Z")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "a.exr").st_mode) == 0o640
    before = (tmp_path / "a.exr").read_bytes()

    class Broken:
        def __init__(self, *a):
            pass

        def __enter__(self):
            raise RuntimeError("disk full")

        def __exit__(self, *a):
            return False

    monkeypatch.setattr(OpenEXR, "File", Broken)
    with pytest.raises(OutputError, match=r"a\.exr: cannot write EXR: disk full"):
        write_exr(tmp_path / "a.exr", np.zeros((2, 3), np.float32), "Z")
    assert (tmp_path / "a.exr").read_bytes() == before and os.listdir(tmp_path) == ["a.exr"]
    with pytest.raises(ValueError, match="does not fit EXR channels"):
        write_exr(tmp_path / "b.exr", np.zeros((2, 3, 2), np.float32), "RGB")


def test_cli_exr_files(tmp_path):
    pytest.importorskip("OpenEXR")
    run = run_rayvr("capture", "--format", "exr", "--aux", "depth,material", "--size", "16x12", "--eye", "left",
                    "--out", tmp_path, "-q")
    assert run.returncode == 0, run.stderr
    assert sorted(os.listdir(tmp_path)) == ["frame_left.exr", "frame_left.png", "frame_left_depth.exr",
                                            "frame_left_material.npy", "frame_timings.json"]
    assert read_exr(tmp_path / "frame_left_depth.exr")["Z"].shape == (12, 16)


def test_missing_openexr_is_one_line_naming_the_extra(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "OpenEXR", None)  # import OpenEXR now fails as if not installed
    assert cli.main(["capture", "--format", "exr", "--out", str(tmp_path / "o"), "--size", "8x8"]) == 2
    err = capsys.readouterr().err
    assert err == "rayvr capture: error: EXR output needs the OpenEXR package: pip install 'rayvr[exr]'\n"
    assert not (tmp_path / "o").exists()
