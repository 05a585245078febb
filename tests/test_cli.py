import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from PIL import Image

from conftest import interrupt_rayvr, run_rayvr
from rayvr.frame.cameras.rig import orbit, save_path


rayvr = run_rayvr  # the CLI in a child process (conftest)


def test_capture_default_scene_stereo_pair_with_aux(tmp_path):
    run = rayvr("capture", "--size", "40x30", "--out", str(tmp_path), "--aux", "depth,normal,material",
                "--timings")
    assert run.returncode == 0, run.stderr
    for eye in ("left", "right"):
        img = np.asarray(Image.open(tmp_path / f"frame_{eye}.png"))
        assert img.shape == (30, 40, 3) and img.dtype == np.uint8 and img.std() > 5
        depth = np.load(tmp_path / f"frame_{eye}_depth.npy")
        assert depth.shape == (30, 40) and np.isfinite(depth).all() and depth.max() > 0
        assert np.load(tmp_path / f"frame_{eye}_normal.npy").shape == (30, 40, 3)
        assert np.load(tmp_path / f"frame_{eye}_material.npy").dtype == np.uint32
    left = np.asarray(Image.open(tmp_path / "frame_left.png")).astype(int)
    right = np.asarray(Image.open(tmp_path / "frame_right.png")).astype(int)
    assert np.abs(left - right).mean() > 0.5  # two different eyes
    assert "gbuffer" in run.stdout and "total" in run.stdout
    summary = json.loads((tmp_path / "frame_timings.json").read_text())
    # the room's own config (rayvr/assets/default_room.toml): shadows, mirrors and glossy are traced
    assert {"rt_shadows", "rt_reflections", "rt_glossy"} <= set(summary["passes"])
    assert "default_room.toml" in run.stderr  # said, in one line
    assert set(summary["gpu_ms_mean"]) | set(summary["gpu_ms_unavailable"]) == set(summary["passes"])
    assert all(0 <= v < 2**31 / 1e6 for v in summary["gpu_ms_mean"].values())  # no wrapped timer values
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_capture_one_eye_debug_view_and_path_replay(tmp_path):
    save_path(tmp_path / "path.json", orbit([0, 1, -1], 3.0, 0.5, 3))
    run = rayvr("capture", "--size", "24x16", "--out", str(tmp_path / "o"), "--eye", "right", "--view", "normal",
                "--path", str(tmp_path / "path.json"), "-q")
    assert run.returncode == 0, run.stderr
    assert sorted(os.listdir(tmp_path / "o")) == [  # the job file and the frames' records let a rerun resume
        "frame_0000_record.json", "frame_0000_right_normal.png", "frame_0001_record.json",
        "frame_0001_right_normal.png", "frame_0002_record.json", "frame_0002_right_normal.png", "frame_job.json",
        "frame_timings.json"]
    frames = [np.asarray(Image.open(tmp_path / "o" / f"frame_000{i}_right_normal.png")) for i in range(3)]
    assert not np.array_equal(frames[0], frames[1])


@pytest.mark.parametrize("args, words", [
    (["--materials", "MISSING"], ["cannot read material config"]),
    (["--size", "0x10"], ["size must be between"]),
    (["--size", "0x0"], ["--size", "size must be between"]),
    (["--size", "garbage"], ["--size", "WIDTHxHEIGHT"]),
    (["--camera", "1,2,3"], ["expected 6"]),
    (["/nonexistent/scene.glb"], ["no such file"]),
    (["--aux", "colour"], ["unknown aux channel", "depth"]),
    (["--fov", "200"], ["fov_y must be in (0, 180)"]),
    (["--fov", "179.9995"], ["planar projection precision ends at tangent 1e+05", "wide-angle camera model"]),
    (["--fov", "nan"], ["--fov", "finite"]),
    (["--fov", "inf"], ["--fov", "finite"]),
    (["--near", "inf"], ["--near", "finite number in (0, 1e+30]"]),
    (["--near", "0"], ["--near", "(0, 1e+30]"]),
    (["--near", "-1"], ["--near", "(0, 1e+30]"]),
    (["--near", "nan"], ["--near", "finite"]),
    (["--near", "2", "--far", "1"], ["far (1.0) must be greater than near (2.0)"]),
    (["--near", "2", "--far", "2"], ["far (2.0) must be greater than near (2.0)"]),
    (["--far", "nan"], ["--far"]),
    (["--exposure", "1e38"], ["--exposure", "(0, 1e+06]"]),
    (["--exposure", "0"], ["--exposure", "(0, 1e+06]"]),
    (["--exposure", "nan"], ["--exposure", "finite"]),
    (["--exposure", "inf"], ["--exposure", "finite"]),
    (["--ipd", "-0.1"], ["--ipd", "[0, 1e+30]"]),
    (["--ipd", "nan"], ["--ipd", "finite"]),
    (["--frames", "0"], ["--frames", "from 1 to"]),
    (["--frames", "-3"], ["--frames", "from 1 to"]),
    (["--spp", "0"], ["--spp", "from 1 to"]),
    (["--denoise-iterations", "9"], ["--denoise-iterations", "from 1 to 6"]),
    (["--traversal", "shadow=bvh3"], ["--traversal", "BVH layout must be one of bvh2, bvh4, bvh8"]),
    (["--traversal", "eyes=bvh4"], ["--traversal", "unknown ray kind 'eyes'"]),
])
def test_capture_bad_input_is_a_clear_error(tmp_path, args, words):
    run = rayvr("capture", "--out", str(tmp_path / "o"), "--size", "8x8", *args)
    assert run.returncode == 2, run.stdout + run.stderr
    assert len(run.stderr.splitlines()) == 1 and run.stderr.startswith("rayvr capture: error: "), run.stderr
    for w in words:
        assert w in run.stderr, run.stderr
    assert not (tmp_path / "o").exists()  # a failed run leaves no empty output folder


@pytest.mark.parametrize("rotation, words", [
    ([[0, 0, 0], [0, 0, 0], [0, 0, 0]], "det 0"),
    ([[2, 0, 0], [0, 2, 0], [0, 0, 2]], "reaches 3"),
    ([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "det -1"),  # a mirror
])
def test_path_pose_that_is_not_a_rotation_is_refused_naming_file_and_pose(tmp_path, rotation, words):
    path = tmp_path / "path.json"
    good = {"position": [0, 1, 3], "target": [0, 1, 0]}
    path.write_text(json.dumps({"poses": [good, good, {"position": [0, 1, 3], "rotation": rotation}]}))
    run = rayvr("capture", "--path", str(path), "--out", str(tmp_path / "o"), "--size", "8x8")
    assert run.returncode == 2, run.stdout + run.stderr
    assert len(run.stderr.splitlines()) == 1, run.stderr
    assert f"{path}: pose 2: rotation is not a rotation matrix" in run.stderr and words in run.stderr, run.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("prefix", ["../X", "sub/X", "/tmp/X", "", "..", ".X", "a\\b", "x" * 201])
def test_prefix_cannot_leave_the_output_folder(tmp_path, prefix):
    run = rayvr("capture", "--out", str(tmp_path / "o"), "--size", "8x8", "--prefix", prefix)
    assert run.returncode == 2, run.stdout + run.stderr
    assert len(run.stderr.splitlines()) == 1 and "argument --prefix: file prefix must be a plain name" in run.stderr
    assert not (tmp_path / "X_left.png").exists() and not list(tmp_path.rglob("*.png"))


def test_bad_config_names_file_and_key(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text('[materials]\nfloor = "sparkle"\n')
    run = rayvr("capture", "--materials", str(cfg), "--out", str(tmp_path / "o"), "--size", "8x8")
    assert run.returncode == 2
    assert str(cfg) in run.stderr and "materials.floor" in run.stderr and "raster" in run.stderr
    assert not (tmp_path / "o").exists()


def test_unwritable_output_fails_before_rendering_and_loses_nothing(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("keep me")
    run = rayvr("capture", "--out", str(blocker / "sub"), "--size", "8x8")
    assert run.returncode == 2 and f"cannot create output folder: {blocker} is not a folder" in run.stderr
    assert blocker.read_text() == "keep me"
    if os.geteuid() != 0:  # root can write anywhere
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        run = rayvr("capture", "--out", str(ro), "--size", "8x8")
        assert run.returncode == 2 and "not writable" in run.stderr


def test_ctrl_c_during_a_sequence_is_one_line_exit_130_and_keeps_whole_files(tmp_path):
    out = tmp_path / "o"
    code, stdout, stderr = interrupt_rayvr(["capture", "--frames", "500", "--size", "320x240", "--out", out, "-q"],
                                           lambda: out.is_dir() and any(p.suffix == ".png" for p in out.iterdir()),
                                           "no frame file appeared", poll_s=0.02)
    assert code == 130, stderr
    assert len(stderr.splitlines()) == 1 and "Traceback" not in stderr, stderr
    assert (out / "frame_job.json").exists()  # written before the first frame: a rerun resumes
    records = sorted(out.glob("frame_*_record.json"))  # each written after its frame's files
    files = sorted(p for p in out.iterdir() if p.name != "frame_job.json" and p not in records)
    assert len(files) == 2 * len(records)
    assert stderr.startswith("rayvr capture: interrupted after ") and f"the {len(files)} file(s) written" in stderr
    assert 0 < len(files) < 1000 and all(p.suffix == ".png" for p in files)  # no temp file, no summary
    for p in files:
        assert np.asarray(Image.open(p)).shape == (240, 320, 3)  # every kept file is whole


def test_output_folder_is_made_with_the_first_file(tmp_path):
    out = tmp_path / "a" / "b"
    run = rayvr("capture", "--out", str(out), "--size", "8x8", "--aux", "depth", "-q")
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in out.iterdir()) == ["frame_left.png", "frame_left_depth.npy", "frame_right.png",
                                                     "frame_right_depth.npy", "frame_timings.json"]


def test_the_built_in_room_renders_its_own_effects_unless_raster_is_asked_for(tmp_path):
    # A first run used to show the room all raster: no shadows, a black mirror ball.
    from rayvr.scene.loader import load

    room = load(None)
    shown, plain = tmp_path / "default", tmp_path / "raster"
    run = rayvr("capture", "--size", "64x48", "--eye", "left", "--aux", "material", "--out", str(shown))
    assert run.returncode == 0, run.stderr
    assert sum("default_room.toml" in line for line in run.stderr.splitlines()) == 1
    run = rayvr("capture", "--size", "64x48", "--eye", "left", "--materials", "raster.toml", "--out", str(plain),
                "-q")  # a shipped config by its file name
    assert run.returncode == 0, run.stderr and "default_room.toml" not in run.stderr
    traced = np.asarray(Image.open(shown / "frame_left.png")).astype(int)
    raster = np.asarray(Image.open(plain / "frame_left.png")).astype(int)
    material = np.load(shown / "frame_left_material.npy")
    names = room.material_names()
    for name in ("mirror", "floor"):  # a reflection; the floor's gloss and the shadows cast on it
        where = material == names.index(name)
        assert where.sum() > 20, name
        assert np.abs(traced[where] - raster[where]).mean() > 4, name


def test_info_lists_gl_and_scene_effects(tmp_path):
    run = rayvr("info", "--json")
    assert run.returncode == 0, run.stderr
    info = json.loads(run.stdout)
    assert info["version_code"] >= 430 and "GL_MAX_SHADER_STORAGE_BLOCK_SIZE" in info["limits"]
    cfg = tmp_path / "c.toml"
    cfg.write_text('[materials]\n"nope" = "raster"\n')
    run = rayvr("info", "--materials", str(cfg))
    assert run.returncode == 0, run.stderr
    assert "mirror" in run.stdout and "raster" in run.stdout and "'nope' matches no material" in run.stdout
    assert "None" not in run.stdout  # a field the driver does not report reads "unknown"


def test_info_names_the_shipped_configs_and_lists_the_room_by_default():
    """`rayvr info --materials raster.toml` takes a shipped config by its bare name, as capture and
    preview do; `rayvr info` alone lists the built-in room's materials with the room's own config."""
    plain = rayvr("info", "--json", "--materials", "raster.toml")
    assert plain.returncode == 0, plain.stderr
    effects = {m["name"]: m["effect"] for m in json.loads(plain.stdout)["scene"]["materials"]}
    assert set(effects.values()) == {"raster"} and "floor" in effects
    own = rayvr("info", "--json")
    assert own.returncode == 0, own.stderr
    effects = {m["name"]: m["effect"] for m in json.loads(own.stdout)["scene"]["materials"]}
    assert effects["floor"] == "glossy" and effects["mirror"] == "reflections"


def test_the_rooms_hint_follows_a_first_look_only(tmp_path):
    """The built-in room's one line about its effects follows a plain capture, not a --views set."""
    hint = "renders with its own effects"
    still = rayvr("capture", "--size", "16x12", "--out", str(tmp_path / "still"))
    assert still.returncode == 0, still.stderr
    assert hint in still.stderr
    views = rayvr("capture", "--size", "16x12", "--views", "sphere:2", "--out", str(tmp_path / "views"))
    assert views.returncode == 0, views.stderr
    assert hint not in views.stderr


def test_a_misspelt_shipped_config_lists_the_shipped_names(tmp_path):
    run = rayvr("capture", "--size", "8x8", "--materials", "rastr.toml", "--out", str(tmp_path))
    assert run.returncode == 2
    line = run.stderr.strip().splitlines()[-1]
    assert "rastr.toml" in line and "raster.toml" in line and "default_room.toml" in line and "Traceback" not in run.stderr


def test_bench_quick_writes_results(tmp_path):
    run = rayvr("bench", "gbuffer", "--quick", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr
    result = json.loads((tmp_path / "gbuffer.json").read_text())
    multiview = result["meta"]["gl_extensions.GL_OVR_multiview2"] if "gl_extensions.GL_OVR_multiview2" in result["meta"] \
        else result["meta"].get("gl_extensions", {}).get("GL_OVR_multiview2")
    assert {r["mode"] for r in result["rows"]} == {"vertex", "geometry", "passes"} | ({"multiview"} if multiview else set())
    assert result["meta"]["gl_renderer"] and (tmp_path / "gbuffer.md").exists()


def test_bench_peers_quick(tmp_path):
    import importlib.util

    # Only look for it: importing pyrender here (without PYGLET_HEADLESS) would reach for X11.
    if importlib.util.find_spec("pyrender") is None:
        pytest.skip("pyrender is an optional peer (pip install pyrender)")
    run = rayvr("bench", "peers", "--quick", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr
    row = json.loads((tmp_path / "peers.json").read_text())["rows"][0]
    assert row["rayvr_fps"] > 0 and (row["pyrender_fps"] or row["pyrender_error"])


def test_capture_accumulates_spp_samples_and_denoises(tmp_path):
    """--spp N: N samples per pixel, each its own sequence (the images differ from 1 sample);
    --denoise filters the sampled effects' pixels (a capture's default: --no-denoise leaves them
    raw); the summary says so; a progress bar counts samples."""
    room = "rayvr/assets/default_room.toml"
    common = ("capture", "--materials", room, "--size", "32x24", "--eye", "left")
    one = rayvr(*common, "--no-denoise", "--out", str(tmp_path / "one"), "-q")
    many = rayvr(*common, "--spp", "3", "--denoise", "--denoise-iterations", "2", "--out", str(tmp_path / "many"))
    assert one.returncode == 0 and many.returncode == 0, one.stderr + many.stderr
    assert "3/3" in many.stderr  # tqdm's bar over the samples
    summary = json.loads((tmp_path / "many" / "frame_timings.json").read_text())
    assert summary["spp"] == 3 and summary["denoise"] == ["glossy", "shadows"]
    assert {"accumulate", "denoise"} <= set(summary["passes"])
    raw = json.loads((tmp_path / "one" / "frame_timings.json").read_text())
    assert raw["denoise"] == [] and "denoise" not in raw["passes"]
    a = np.asarray(Image.open(tmp_path / "one" / "frame_left.png")).astype(int)
    b = np.asarray(Image.open(tmp_path / "many" / "frame_left.png")).astype(int)
    assert a.shape == b.shape and np.abs(a - b).mean() > 0.5 and b.std() > 5


def test_bench_rays_bad_layout_is_a_clear_error(tmp_path):
    run = rayvr("bench", "rays", "--layouts", "bvh2,bvh16", "--out", str(tmp_path / "b"))
    assert run.returncode == 2, run.stdout + run.stderr
    assert len(run.stderr.splitlines()) == 1 and "BVH layouts must be among bvh2, bvh4, bvh8" in run.stderr
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("args", [("bench", "ssrt", "--quick"), ("bench", "crosscheck", "--quick"),
                                  ("capture", "--size", "16x12", "--budget-ms", "5")])
def test_a_missing_optional_extra_is_one_line_before_any_work(tmp_path, args):
    """A command that measures with FLIP (or renders Mitsuba references) where the package is
    absent: one line naming the extra, exit 2, no traceback, nothing written, and at once."""
    blocked = tmp_path / "blocked"
    for module in ("flip_evaluator", "mitsuba"):  # importing either fails, as where it is not installed
        (blocked / module).mkdir(parents=True)
        (blocked / module / "__init__.py").write_text("raise ImportError('not installed')\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(blocked), os.environ.get("PYTHONPATH")]))}
    out = tmp_path / "out"
    start = time.monotonic()
    run = subprocess.run([sys.executable, "-m", "rayvr", *args, "--out", str(out)], capture_output=True, text=True,
                         env=env, timeout=120)
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'rayvr[" in lines[0], run.stderr
    assert not out.exists()
    assert time.monotonic() - start < 30  # refused before rendering or measuring


def test_preview_without_a_display_is_one_line_with_glfws_reason():
    """No display: one line that carries GLFW's own reason, not a Python warning beside it."""
    pytest.importorskip("glfw", reason="GLFW's reason needs the glfw package (its absence: the next test)")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    run = subprocess.run([sys.executable, "-m", "rayvr", "preview", "--frames", "1"], capture_output=True, text=True,
                         env=env, timeout=120)
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert lines[0].startswith("rayvr preview: error: glfw: init failed (") and "DISPLAY" in lines[0], lines[0]


def test_preview_without_the_glfw_package_is_one_line(tmp_path):
    """glfw missing from the Python path (a bare PYTHONPATH install, as on the GPU host) is one line
    that names the package, not an ImportError's traceback."""
    hide = tmp_path / "hide"
    hide.mkdir()
    (hide / "glfw.py").write_text("raise ImportError('No module named glfw')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(hide), os.environ.get("PYTHONPATH", "")]))
    run = subprocess.run([sys.executable, "-m", "rayvr", "preview", "--frames", "1"], capture_output=True, text=True,
                         env=env, timeout=120)
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert lines[0].startswith("rayvr preview: error: glfw: the Python package cannot be imported") \
        and "pip install glfw" in lines[0], lines[0]


@pytest.mark.parametrize("args, says", [
    (("--msaa", "4", "--primary", "raster"), "--primary raster: --msaa 4 casts sub-rays"),
    (("--camera-model", "wide", "--primary", "raster"), "--primary raster: the wide camera cannot be rasterized"),
    (("--dof-diameter", "0.1", "--camera-model", "wide"), "the wide camera is not a pinhole"),
    (("--dof-diameter", "0.1", "--camera-model", "dof"), "use its aperture parameter"),
    (("--dof-diameter", "0.1", "--stereo", "warp"), "stereo mode 'warp' makes an eye from the other's frame: use --stereo dual"),
    (("--dof-diameter", "0.1", "--stereo", "reuse"), "stereo mode 'reuse' makes an eye from the other's frame: use --stereo dual")])
def test_flags_a_frame_would_ignore_are_one_line(tmp_path, args, says):
    """A flag the frame cannot honour (it used to be dropped, the frame rendered without it) is
    refused in one line, before anything is written."""
    run = rayvr("capture", "--size", "16x12", *args, "--out", tmp_path / "out")
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and says in lines[0], run.stderr
    assert not (tmp_path / "out").exists()


def test_the_renderer_refuses_depth_of_field_it_cannot_apply(gl):
    """The API as the CLI: a frame plan with --dof-diameter under warp (no frame of its own for the
    blur to use) is an error, not a frame without the blur; one eye is a frame of its own."""
    from rayvr import Renderer
    from rayvr.renderer import RenderSettings

    with Renderer(gl=gl, settings=RenderSettings(dof_diameter=0.1, stereo="warp")) as r:
        with pytest.raises(ValueError, match="depth of field"):
            r.plan(eyes=2)
        assert r.plan(eyes=1).dof  # one eye: a dual frame, blurred
    with Renderer(gl=gl, settings=RenderSettings(dof_diameter=0.1)) as r:
        assert r.plan(eyes=2).dof


def test_default_primary_follows_the_camera_and_msaa(tmp_path):
    """Without --primary the frame takes the raster where it can and rays where it must."""
    for args in (("--camera-model", "wide"), ("--msaa", "4"), ()):
        run = rayvr("capture", "--size", "16x12", *args, "--out", tmp_path / "o", "-q")
        assert run.returncode == 0, run.stderr
        passes = json.loads((tmp_path / "o" / "frame_timings.json").read_text())["passes"]
        assert ("primary_rays" in passes) == bool(args), (args, passes)


@pytest.mark.parametrize("kind, kw, says", [
    ("settings", {"exposure": "a"}, "exposure must be a number"),
    ("settings", {"seed": -1}, "seed must be a whole number"),
    ("settings", {"seed": 2 ** 32}, "seed must be a whole number"),
    ("rig", {"size": (10.5, 10)}, "image size must be whole numbers")])
def test_settings_of_the_wrong_type_or_range_are_one_value_error(kind, kw, says):
    """The API's settings: a wrong type or a value the GPU's uint would wrap is a ValueError
    naming the setting (not numpy's TypeError, not a silently wrapped seed)."""
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import RenderSettings

    with pytest.raises(ValueError, match=says):
        (RenderSettings if kind == "settings" else StereoRig)(**kw)


@pytest.mark.parametrize("command", ["capture", "preview"])
def test_the_rigs_pose_is_pose_and_camera_is_its_old_name(command):
    """--pose places the rig (the camera model is --camera-model); --camera still means the same."""
    from rayvr.cli import build_parser

    parse = build_parser().parse_args
    new = parse([command, "--pose", "0,1,3,0,1,-1"])
    old = parse([command, "--camera", "0,1,3,0,1,-1"])
    assert tuple(new.pose) == tuple(old.pose) == (0.0, 1.0, 3.0, 0.0, 1.0, -1.0)


def test_bench_writes_outside_the_committed_results_unless_told():
    from rayvr.cli import build_parser

    args = build_parser().parse_args(["bench", "gbuffer", "--quick"])
    assert os.path.normpath(args.out) == "bench-out"  # was bench/results, the committed results
    assert build_parser().parse_args(["bench", "gbuffer", "--out", "x"]).out == "x"
