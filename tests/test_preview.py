"""The desktop preview: the input state machine and layouts without GL, then the real window
under Xvfb.

Window tests run in a worker process (spawned, one per module): a glfw/GLX context and the
session's headless EGL context must not share a process (moderngl objects belong to the context
current when they were made). The worker returns plain data; the asserts are here, and the
headless reference images come from this process's EGL context.
"""
from __future__ import annotations

import math
import multiprocessing
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from rayvr.scene import materials
from rayvr.frame.cameras.rig import Pose, StereoRig
from rayvr.app.preview import KEYS, RES_SCALES, STEREO_MODES, Camera, Controls, ViewState, layout_for
from rayvr.renderer import VIEWS

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ state machine, no GL

def make_controls(**state):
    rig = StereoRig(Pose.look_at([0.0, 0.0, 5.0], [0.0, 0.0, 0.0]), ipd=0.064, size=(64, 48))
    return Controls(Camera(rig, center=(0.0, 0.0, 0.0), extent=2.0), ViewState(**state))


def tap(c, name, **mods):
    c.key(name, "press", **mods)
    c.key(name, "release", **mods)


def test_tab_and_number_keys_pick_the_stereo_mode():
    c = make_controls()
    seen = [c.state.stereo]
    for _ in STEREO_MODES:
        tap(c, "TAB")
        seen.append(c.state.stereo)
    assert seen == list(STEREO_MODES) + [STEREO_MODES[0]]
    tap(c, "TAB", shift=True)
    assert c.state.stereo == STEREO_MODES[-1]
    for i, mode in enumerate(STEREO_MODES, start=1):
        tap(c, str(i))
        assert c.state.stereo == mode


def test_v_cycles_colour_and_every_debug_view():
    c = make_controls()
    seen = []
    for _ in VIEWS:
        seen.append(c.state.view)
        tap(c, "V")
    assert seen == list(VIEWS) and c.state.view == "color"
    tap(c, "V", shift=True)
    assert c.state.view == VIEWS[-1]


def test_override_cycles_implemented_effects_only():
    c = make_controls()
    seen = [c.state.override]
    for _ in range(len(materials.implemented_effects()) + 1):
        tap(c, "O")
        seen.append(c.state.override)
    assert seen == [None, *materials.implemented_effects(), None]


def test_held_w_flies_forward_at_the_speed_and_shift_is_faster():
    c = make_controls()
    cam = c.camera
    start = cam.position.copy()
    c.key("W", "press")
    c.update(0.5)
    step = cam.position - start
    assert np.allclose(step, [0.0, 0.0, -cam.speed * 0.5])
    c.key("LEFT_SHIFT", "press")
    before = cam.position.copy()
    c.update(0.5)
    assert np.allclose(cam.position - before, 4 * step)
    c.key("W", "release")
    c.key("LEFT_SHIFT", "release")
    before = cam.position.copy()
    c.update(0.5)
    assert np.array_equal(cam.position, before)
    for key, axis, sign in (("D", 0, 1), ("A", 0, -1), ("E", 1, 1), ("Q", 1, -1), ("S", 2, 1)):
        before = cam.position.copy()
        c.key(key, "press")
        c.update(0.1)
        c.key(key, "release")
        assert np.sign((cam.position - before)[axis]) == sign, key


def test_mouse_drag_looks_around_and_plain_motion_does_not():
    c = make_controls()
    cam = c.camera
    c.cursor(10, 10)
    c.cursor(60, 10)  # not dragging
    assert np.allclose(cam.forward, [0, 0, -1])
    c.mouse_button("left", True)
    c.cursor(110, 10)  # drag right: turn right (towards +x)
    c.cursor(110, 60)  # drag down: look down
    c.mouse_button("left", False)
    f = cam.forward
    assert f[0] > 0.1 and f[1] < -0.1
    assert math.isclose(cam.yaw, -50 * 0.004, rel_tol=1e-9)  # 50 px drag
    assert np.allclose(cam.pose.rotation[:, 2], -f)  # the pose looks where the camera does
    assert abs(cam.pose.rotation[1, 0]) < 1e-12  # no roll: the right vector stays horizontal


def test_orbit_keeps_looking_at_the_centre_and_wheel_changes_distance():
    c = make_controls()
    cam = c.camera
    c.cursor(0, 0)
    tap(c, "F")
    assert cam.mode == "orbit" and math.isclose(cam.distance, 5.0)
    c.mouse_button("left", True)
    c.cursor(200, -80)
    c.mouse_button("left", False)
    assert math.isclose(np.linalg.norm(cam.position), 5.0)
    assert np.allclose(cam.position + cam.forward * 5.0, 0.0, atol=1e-12)
    c.scroll(2)
    assert math.isclose(cam.distance, 5.0 * 0.81)
    assert np.allclose(cam.position + cam.forward * cam.distance, 0.0, atol=1e-12)
    tap(c, "F")
    assert cam.mode == "fly"
    speed = cam.speed
    c.scroll(1)
    assert math.isclose(cam.speed, speed * 1.25)
    tap(c, "R")
    assert cam.mode == "fly" and np.allclose(cam.position, [0, 0, 5])


def test_ipd_convergence_and_resolution_keys():
    c = make_controls(res_scale=1.0)
    cam = c.camera
    tap(c, "EQUAL")
    assert math.isclose(cam.ipd, 0.064 * 1.25)
    for _ in range(20):
        tap(c, "MINUS")
    assert cam.ipd == 0.0  # stepping down ends at mono
    tap(c, "EQUAL")
    assert cam.ipd > 0
    assert cam.convergence is None
    tap(c, "C")
    assert math.isclose(cam.convergence, 5.0)
    tap(c, "RIGHT_BRACKET")
    assert math.isclose(cam.convergence, 6.25)
    assert c.camera.rig((64, 48)).convergence == cam.convergence
    tap(c, "C")
    assert cam.convergence is None
    tap(c, "COMMA")
    assert c.state.res_scale == 0.75
    for _ in range(10):
        tap(c, "PERIOD")
    assert c.state.res_scale == RES_SCALES[-1]


def test_toggles_ignore_key_repeat_and_actions_are_queued():
    c = make_controls()
    c.key("H", "press")
    c.key("H", "repeat")
    c.key("H", "repeat")
    assert c.state.help
    c.key("ESCAPE", "press")
    assert not c.state.help and not c.state.quit  # Esc closes the help first
    for name in ("F12", "L", "T", "Y", "P"):
        tap(c, name)
    assert c.take_actions() == ["screenshot", "reload", "quadtree", "vsync", "record"]
    assert c.take_actions() == []
    assert c.state.recording and not c.state.vsync
    tap(c, "F2")
    assert not c.state.hud
    tap(c, "ESCAPE")
    assert c.state.quit


def test_help_lists_every_key_the_state_machine_handles():
    text = " ".join(k for k, _ in KEYS)
    for label in ("W A S D", "Tab", "F12", "Esc", "O", "T", "P", "Y", "F2"):
        assert label in text


def test_layouts_split_the_window_and_map_the_cursor_to_eye_texels():
    sbs = layout_for("side-by-side", (200, 100))
    assert sbs.eyes == "both" and sbs.eye_size == (100, 100)
    assert sbs.viewports == [(0, 0, 100, 100, 0), (100, 0, 100, 100, 1)]
    cross = layout_for("cross-eyed", (200, 100))
    assert [v[4] for v in cross.viewports] == [1, 0]  # right eye on the left
    assert layout_for("anaglyph", (200, 100)).anaglyph
    half = layout_for("right", (200, 100), scale=0.5)
    assert half.eyes == "right" and half.eye_size == (100, 50)
    # Top-left framebuffer pixel -> top row of the eye (GL rows count from the bottom).
    assert sbs.texel_at(0, 0, 100) == (0, 99, 0)
    assert sbs.texel_at(150, 99.5, 100) == (50, 0, 1)
    assert half.texel_at(199, 0, 100) == (99, 49, 0)
    assert sbs.texel_at(250, 10, 100) is None
    with pytest.raises(ValueError, match="stereo mode"):
        layout_for("wobble", (10, 10))


def test_hud_wrap_fits_lines_to_the_width():
    from rayvr.app.preview import _wrap

    lines = _wrap("aaa bbb ccc ddd", 7, len)
    assert lines == ["aaa bbb", "ccc ddd"]


# -------------------------------------------------------------------- the window (Xvfb)

@pytest.fixture(scope="session")
def display():
    """A private Xvfb for this test session (DISPLAY set for this process and its children),
    or the existing display where Xvfb is not installed."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        if os.environ.get("DISPLAY"):
            yield os.environ["DISPLAY"]
            return
        pytest.skip("no display for window tests: Xvfb is not installed (apt-get install xvfb) and DISPLAY is unset")
    read_fd, write_fd = os.pipe()
    log = tempfile.TemporaryFile()
    # -displayfd: Xvfb picks a free display number and writes it to the pipe once it is ready.
    proc = subprocess.Popen([xvfb, "-displayfd", str(write_fd), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                            pass_fds=(write_fd,), stdout=subprocess.DEVNULL, stderr=log)
    os.close(write_fd)
    number = b""
    deadline = time.monotonic() + 20
    while not number.endswith(b"\n") and time.monotonic() < deadline and proc.poll() is None:
        if select.select([read_fd], [], [], 0.2)[0]:
            chunk = os.read(read_fd, 16)
            if not chunk:
                break
            number += chunk
    os.close(read_fd)
    if not number.strip().isdigit():
        proc.kill()
        proc.wait()
        log.seek(0)
        pytest.skip(f"Xvfb did not start: {log.read().decode(errors='replace')[-500:]}")
    saved = {k: os.environ.get(k) for k in ("DISPLAY", "WAYLAND_DISPLAY")}
    os.environ["DISPLAY"] = f":{number.decode().strip()}"
    os.environ.pop("WAYLAND_DISPLAY", None)  # glfw would prefer Wayland
    try:
        yield os.environ["DISPLAY"]
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture(scope="module")
def worker(display):
    """Runs module-level functions in a spawned process that owns the glfw windows."""
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield lambda fn, *args: pool.submit(fn, *args).result(timeout=240)


def _preview(**kw):
    from rayvr.app.preview import Preview

    kw.setdefault("vsync", False)
    kw.setdefault("res_scale", 1.0)
    return Preview(kw.pop("scene", None), kw.pop("materials", None), **kw)


def _press(p, key, mods=0):
    import glfw

    p.on_key(p.window, key, 0, glfw.PRESS, mods)
    p.on_key(p.window, key, 0, glfw.RELEASE, mods)


def _window_images(size):
    """The window, HUD off, in each stereo mode; plus the rig it used."""
    p = _preview(size=size, hud=False)
    try:
        out = {}
        for mode in STEREO_MODES:
            p.state.stereo = mode
            p.frame()
            out[mode] = p.frame(grab=True)
        return out, p.camera.rig((1, 1)), p.gl_name
    finally:
        p.close()


def test_window_shows_exactly_the_headless_capture(worker, gl):
    from rayvr import Renderer

    w, h = 96, 48
    images, rig, gl_name = worker(_window_images, (2 * w, h))
    assert isinstance(gl_name, str) and gl_name.strip(), f"the window's context names no GL renderer: {gl_name!r}"
    with Renderer(None, None, gl=gl) as r:
        half = r.render(rig.with_size((w, h)))
        full = r.render(rig.with_size((2 * w, h)))
    for mode, img in images.items():
        assert img.shape == (h, 2 * w, 3), mode
        assert img.std() > 10, f"{mode}: the window is blank"

    def close(a, b, what):
        diff = np.abs(a.astype(int) - b.astype(int))
        assert diff.max() <= 2 and diff.mean() < 0.05, f"{what}: max {diff.max()}, mean {diff.mean():.3f}"

    close(images["left"], full.left.color, "left eye")
    close(images["right"], full.right.color, "right eye")
    close(images["side-by-side"][:, :w], half.left.color, "side-by-side, left half")
    close(images["side-by-side"][:, w:], half.right.color, "side-by-side, right half")
    close(images["cross-eyed"][:, :w], half.right.color, "cross-eyed, left half")
    close(images["cross-eyed"][:, w:], half.left.color, "cross-eyed, right half")
    lum = full.left.color.astype(float) @ [0.299, 0.587, 0.114]
    expected = np.dstack([lum, full.right.color[..., 1], full.right.color[..., 2]])
    diff = np.abs(images["anaglyph"].astype(float) - expected)
    assert diff.max() <= 2.5, f"anaglyph: max {diff.max()}"


def _window_stereo_methods(size):
    """The window (side-by-side, HUD off) with each way of making the second eye (B cycles)."""
    p = _preview(size=size, hud=False)  # all raster: no sampled effect for the preview to accumulate
    try:
        out = {}
        for _ in range(3):
            p.frame()
            out[p.state.method] = (p.frame(grab=True), p.last_frame.plan.stereo, p.last_frame.pass_names)
            _press(p, __import__("glfw").KEY_B)
        return out, p.camera.rig((1, 1)), " ".join(t for t, _ in p.hud_lines(p.last_layout, (size[0], size[1])))
    finally:
        p.close()


def test_window_shows_each_stereo_method_as_captured(worker, gl):
    from rayvr import Renderer
    from rayvr.renderer import RenderSettings

    w, h = 64, 48
    images, rig, hud = worker(_window_stereo_methods, (2 * w, h))
    assert set(images) == {"dual", "warp", "reuse"} and "second eye: dual" in hud
    for method, (img, planned, passes) in images.items():
        assert planned == method
        assert ("warp" in passes) == (method == "warp") and ("reuse_map" in passes) == (method == "reuse")
        with Renderer(None, None, gl=gl, settings=RenderSettings(stereo=method)) as r:
            f = r.render(rig.with_size((w, h)))
        for half, eye in ((img[:, :w], f.left.color), (img[:, w:], f.right.color)):
            diff = np.abs(half.astype(int) - eye.astype(int))
            assert diff.max() <= 2 and diff.mean() < 0.05, (method, diff.max(), diff.mean())


def _events():
    import glfw

    from rayvr.renderer import VIEWS

    p = _preview(size=(128, 48), res_scale=0.5)
    try:
        out = {}
        p.frame()
        start = p.camera.pose
        _press(p, glfw.KEY_TAB)
        p.frame()
        out["after_tab"] = (p.state.stereo, p.last_frame.plan.eyes)
        _press(p, glfw.KEY_4)
        _press(p, glfw.KEY_V)
        p.frame()
        out["after_4_v"] = (p.state.stereo, p.state.view, p.last_frame.plan.view, p.last_frame.plan.eyes,
                            VIEWS[1])
        _press(p, glfw.KEY_V, glfw.MOD_SHIFT)
        p.on_key(p.window, glfw.KEY_W, 0, glfw.PRESS, 0)
        p.frame()
        time.sleep(0.05)
        p.frame()
        p.on_key(p.window, glfw.KEY_W, 0, glfw.RELEASE, 0)
        moved = p.camera.pose.position - start.position
        out["moved_forward"] = float(moved @ start.forward)
        out["speed"] = p.camera.speed
        yaw = p.camera.yaw
        p.on_cursor_pos(p.window, 20, 20)
        p.on_mouse_button(p.window, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
        p.on_cursor_pos(p.window, 70, 20)
        p.on_mouse_button(p.window, glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)
        out["turned"] = yaw - p.camera.yaw  # dragged right: turned right
        _press(p, glfw.KEY_O)
        p.frame()
        out["override"] = (p.state.override, p.renderer.config.source, p.renderer.config.default)
        for _ in materials.implemented_effects():  # the cycle is off -> each effect -> off
            _press(p, glfw.KEY_O)
        p.frame()
        out["override_off"] = (p.state.override, p.renderer.config.source)
        _press(p, glfw.KEY_EQUAL)
        _press(p, glfw.KEY_C)
        _press(p, glfw.KEY_PERIOD)
        p.frame()
        rig = p.camera.rig((1, 1))
        out["rig"] = (rig.ipd, rig.convergence, p.state.res_scale, p.last_frame.gbuffer.size)
        _press(p, glfw.KEY_T)
        p.frame()
        out["quadtree_message"] = p.message
        _press(p, glfw.KEY_R)
        out["reset"] = bool(np.allclose(p.camera.pose.position, start.position))
        p.on_cursor_pos(p.window, 30, 30)
        p.frame()
        out["hud"] = [t for t, _ in p.hud_lines(p.last_layout, (128, 48))]
        glfw.set_window_size(p.window, 100, 40)  # resizing: the next frame follows the window
        glfw.poll_events()
        p.frame()
        out["resized"] = (p.last_layout.eye_size, p.last_frame.gbuffer.size)
        _press(p, glfw.KEY_ESCAPE)
        out["should_close"] = p.should_close()
        return out
    finally:
        p.close()


def test_synthetic_key_and_mouse_events_drive_the_window(worker):
    out = worker(_events)
    assert out["after_tab"] == ("cross-eyed", 2)
    stereo, view, planned, layers, second_view = out["after_4_v"]
    assert (stereo, view, planned, layers) == ("left", second_view, second_view, 1)
    assert 0 < out["moved_forward"] <= out["speed"] * 0.25  # W for two short frames
    assert math.isclose(out["turned"], 50 * 0.004, rel_tol=1e-9)
    effect = materials.implemented_effects()[0]
    assert out["override"] == (effect, f"override:{effect}", effect)
    assert out["override_off"] == (None, "<defaults>")
    ipd, convergence, scale, gb_size = out["rig"]
    assert math.isclose(ipd, 0.064 * 1.25) and convergence > 0 and scale == 0.75
    assert gb_size == (96, 36)  # 'left' mode: one eye fills the 128x48 window, at scale 0.75
    # T: the next quadtree preset for the ssr materials (none here: the message says so)
    assert "quadtree thresholds: 3 deg, 1e-5" in out["quadtree_message"] and "no material uses ssr" in out["quadtree_message"]
    assert out["reset"]
    hud = " ".join(out["hud"])
    for needle in ("ms/frame", "GPU ms", "gbuffer", "left  view", "scale 0.75", "cursor: ", "IPD"):
        assert needle in hud, needle
    assert out["resized"] == ((75, 30), (75, 30))
    assert out["should_close"]


def _second_effect():
    return next((e for e in materials.implemented_effects() if e != "raster"), "shadows")


def _config_reload(cfg_path):
    from rayvr.frame.gbuffer import NO_HIT

    effect = _second_effect()
    cfg = Path(cfg_path)

    def write(text):
        before = cfg.stat().st_mtime_ns if cfg.exists() else 0
        cfg.write_text(text)
        os.utime(cfg, ns=(before + 10**9, before + 10**9))  # a coarse-mtime filesystem must see a change

    def effect_ids(p):
        m = np.frombuffer(p.last_frame.gbuffer.textures["material"].read(), np.uint32).reshape(-1, 2)
        hit = m[:, 0] != NO_HIT
        return {int(i): sorted(set(m[hit & (m[:, 0] == i), 1].tolist())) for i in np.unique(m[hit, 0])}

    write('default = "raster"\n')
    p = _preview(size=(64, 48), materials=cfg, stereo="left")
    try:
        names = p.renderer.scene.material_names()
        out = {"names": names, "effect_id": materials.EFFECTS[effect].id, "effect": effect}
        p.frame()
        out["ids0"] = effect_ids(p)
        write(f'default = "raster"\n[materials]\n"floor" = "{effect}"\n"box_*" = "{effect}"\n')
        p.frame()  # the next frame
        out["ids1"] = effect_ids(p)
        write('default = "warp9"\n')  # unknown effect
        p.frame()
        out["bad_effect"] = (p.config_error, effect_ids(p), [t for t, _ in p.hud_lines(p.last_layout, (64, 48))])
        write('default = "raster"\n[materials\n')  # TOML syntax error
        p.frame()
        out["bad_toml"] = (p.config_error, effect_ids(p))
        cfg.unlink()  # an editor that deletes and rewrites
        p.frame()
        out["missing"] = (p.config_error, effect_ids(p))
        write('default = "raster"\n')
        p.frame()
        out["fixed"] = (p.config_error, effect_ids(p))
        # A valid config whose passes fail to build (a new pass with a shader bug, say).
        record = p.renderer.record

        def failing_record(*args, **kw):
            if effect in p.renderer.effects_in_use():
                raise RuntimeError(f"pass for {effect} failed to build")
            return record(*args, **kw)

        p.renderer.record = failing_record
        write(f'default = "{effect}"\n')
        p.frame()
        out["unrenderable"] = (p.config_error, effect_ids(p), p.renderer.config.default)
        return out
    finally:
        p.close()


def test_config_edits_on_disk_change_effect_ids_on_the_next_frame(worker, tmp_path):
    out = worker(_config_reload, str(tmp_path / "materials.toml"))
    names, eid = out["names"], out["effect_id"]
    changed = {i for i, n in enumerate(names) if n == "floor" or n.startswith("box_")}
    assert out["ids0"] and all(v == [0] for v in out["ids0"].values())
    assert changed & set(out["ids1"]), "the changed materials are not on screen"
    for i, ids in out["ids1"].items():
        assert ids == ([eid] if i in changed else [0]), names[i]
    error, ids, hud = out["bad_effect"]
    assert "warp9" in error and "default" in error and "materials.toml" in error
    assert ids == out["ids1"]  # the last good config stays
    hud = " ".join(hud)
    assert "config error" in hud and "warp9" in hud
    error, ids = out["bad_toml"]
    assert "not valid TOML" in error and ids == out["ids1"]
    error, ids = out["missing"]
    assert "cannot read" in error and ids == out["ids1"]
    error, ids = out["fixed"]
    assert error is None and all(v == [0] for v in ids.values())
    error, ids, default = out["unrenderable"]
    assert "rendering failed, reverted" in error and "failed to build" in error
    assert default == "raster" and ids == out["fixed"][1]


def _screenshot(out_dir):
    import glfw

    p = _preview(size=(128, 48), hud=False, out_dir=out_dir)
    try:
        p.frame()
        _press(p, glfw.KEY_F12)
        p.frame()
        first = [str(f) for f in p.last_files]
        _press(p, glfw.KEY_2)
        _press(p, glfw.KEY_F12)
        p.frame()
        return first, [str(f) for f in p.last_files]
    finally:
        p.close()


def test_screenshot_key_writes_what_rayvr_capture_writes(worker, tmp_path):
    from PIL import Image

    from rayvr.app.capture import CaptureJob, file_name

    first, second = worker(_screenshot, str(tmp_path))
    rig = StereoRig(size=(64, 48))
    job = CaptureJob(rig, [rig.pose], "both", "color", (), tmp_path, "preview_0001")
    expected = [file_name(job, 0, e, "color", "png") for e in ("left", "right")]
    expected += [tmp_path / "preview_0001_timings.json", tmp_path / "preview_0001_window.png"]
    assert [Path(f) for f in first] == expected
    left, right, window = (np.asarray(Image.open(f)) for f in (expected[0], expected[1], expected[3]))
    assert left.shape == (48, 64, 3) and window.shape == (48, 128, 3)
    # The window below the HUD panel shows the same pixels as the files.
    assert np.abs(window[-8:, :64].astype(int) - left[-8:]).max() <= 1
    assert np.abs(window[-8:, 64:].astype(int) - right[-8:]).max() <= 1
    assert [Path(f).name for f in second] == ["preview_0002_left.png", "preview_0002_right.png",
                                             "preview_0002_timings.json", "preview_0002_window.png"]


def _record(path_file):
    import glfw

    p = _preview(size=(64, 48), path_file=path_file, stereo="left")
    try:
        p.frame()
        _press(p, glfw.KEY_P)
        p.on_key(p.window, glfw.KEY_D, 0, glfw.PRESS, 0)
        for _ in range(6):
            time.sleep(0.04)
            p.frame()
        p.on_key(p.window, glfw.KEY_D, 0, glfw.RELEASE, 0)
        _press(p, glfw.KEY_P)
        p.frame()
        return p.message
    finally:
        p.close()


def test_recorded_camera_path_replays_in_capture(worker, gl, tmp_path):
    from rayvr import Renderer
    from rayvr.app.capture import CaptureJob, poses_for, run_capture

    path_file = tmp_path / "path.json"
    message = worker(_record, str(path_file))
    assert "camera path saved" in message
    with Renderer(None, None, gl=gl) as r:
        rig = StereoRig.for_scene(r.scene, size=(16, 12))
        poses = poses_for(rig, r.scene, path=str(path_file))  # what `rayvr capture --path` does
        assert len(poses) >= 3
        xs = [(p.position - poses[0].position) @ poses[0].rotation[:, 0] for p in poses]
        assert all(b > a for a, b in zip(xs, xs[1:]))  # D strafes right, pose after pose
        summary = run_capture(r, CaptureJob(rig, poses, "left", out_dir=tmp_path / "replay"), progress=False)
    assert summary["frames"] == len(poses)


def test_app_py_opens_renders_and_closes(display, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    res = subprocess.run([sys.executable, str(REPO / "app.py"), "--size", "64x48", "--frames", "2",
                          "--out", str(tmp_path)], capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    res = subprocess.run([sys.executable, str(REPO / "app.py"), "--materials", str(tmp_path / "nope.toml"),
                          "--size", "64x48", "--frames", "1"], capture_output=True, text=True, timeout=120,
                         env=env, cwd=tmp_path)
    assert res.returncode == 0 and "cannot read" in res.stderr  # opens anyway, says why


def test_quadtree_key_steps_the_ssr_thresholds_of_the_config():
    """T sets (gamma_norm, gamma_dist) of every ssr material, per-material entries included, and
    cycles back to lossless."""
    from rayvr.scene.materials import parse_config
    from rayvr.app.preview import QUADTREE_PRESETS, Preview

    class Fake:  # the parts of Preview that T uses, without a window
        quadtree_preset = 0
        file_config = parse_config({"materials": {"floor": {"effect": "ssr", "gamma_dist": 0.5}, "wall": "shadows"}},
                                   "t")
        messages = []

        def _apply_materials(self):
            pass

        def say(self, text):
            self.messages.append(text)

        class renderer:
            @staticmethod
            def effects_in_use():
                return frozenset({"ssr"})

    p = Fake()
    seen = []
    for _ in range(len(QUADTREE_PRESETS)):
        Preview.cycle_quadtree_thresholds(p)
        a = p.file_config.assign(["floor", "wall"], warn=False)
        seen.append((a[0].params["gamma_norm"], a[0].params["gamma_dist"]))
        assert a[1].effect == "shadows" and "gamma_norm" not in a[1].params
    assert seen == [(g, d) for _, g, d in QUADTREE_PRESETS[1:] + QUADTREE_PRESETS[:1]]
    assert "no material uses ssr" not in p.messages[-1] and "lossless" in p.messages[-1]


def test_noise_keys_toggle_accumulation_denoiser_and_temporal_reprojection():
    from rayvr.render_options.denoise import MAX_DENOISE_ITERATIONS

    c = make_controls()
    assert c.state.accumulate and not c.state.denoise and not c.state.temporal  # accumulate while still
    for k in ("M", "N", "G"):
        tap(c, k)
    assert not c.state.accumulate and c.state.denoise and c.state.temporal
    c.key("M", "repeat")  # toggles ignore auto-repeat
    assert not c.state.accumulate
    for _ in range(10):
        tap(c, "I")
    assert c.state.denoise_iterations == MAX_DENOISE_ITERATIONS
    for _ in range(10):
        tap(c, "I", shift=True)
    assert c.state.denoise_iterations == 1
    text = " ".join(k for k, _ in KEYS)
    assert all(k in text for k in ("M", "N", "I, Shift+I", "G"))


def _accumulating():
    import glfw

    p = _preview(size=(96, 36), materials="rayvr/assets/default_room.toml", hud=True)
    try:
        out = {}
        for _ in range(3):
            p.frame()
        out["still"] = (p.renderer.accumulator.sample, p.last_frame.plan.accumulate,
                        [t for t, _ in p.hud_lines(p.last_layout, (96, 36)) if t.startswith("samples")])
        p.on_key(p.window, glfw.KEY_D, 0, glfw.PRESS, 0)  # a move starts over
        p.frame()
        p.on_key(p.window, glfw.KEY_D, 0, glfw.RELEASE, 0)
        out["moved"] = p.renderer.accumulator.sample
        _press(p, glfw.KEY_N)
        p.frame()
        out["denoise"] = (p.last_frame.plan.denoise, p.renderer.settings.denoise, p.renderer.accumulator.sample)
        return out
    finally:
        p.close()


def test_preview_accumulates_while_still_and_a_move_starts_over(worker):
    out = worker(_accumulating)
    sample, accumulate, hud = out["still"]
    assert accumulate and sample == 2 and hud and hud[0].startswith("samples 3"), out
    assert out["moved"] == 0
    denoised, on, sample = out["denoise"]
    assert on and set(denoised) == {"shadows", "glossy"} and sample == 0  # a settings change starts over too


def _temporal_key(camera):
    import glfw

    p = _preview(size=(64, 24), materials="rayvr/assets/default_room.toml", hud=True, rig_options={"camera": camera})
    try:
        p.frame()
        _press(p, glfw.KEY_G)
        p.frame()
        return p.state.temporal, p.renderer.settings.temporal, p.config_error
    finally:
        p.close()


def test_temporal_key_on_a_camera_it_cannot_reproject_stays_off_with_a_note(worker):
    """G asks for temporal reprojection, which Renderer.plan refuses for a camera without planar
    frusta: the preview keeps rendering with it off and says why; the pinhole takes it."""
    state, setting, note = worker(_temporal_key, "wide")
    assert not state and not setting and "temporal reprojection" in note and "wide camera" in note, note
    assert worker(_temporal_key, "pinhole") == (True, True, None)


# ------------------------------------------------------------------- the HUD's layout

def _atlas_measure(size):
    from rayvr.app.hud import FontAtlas

    font = FontAtlas(size)
    return font.line_height, font.width


@pytest.mark.parametrize("window", [(1280, 720), (960, 540), (640, 360), (600, 400)])
def test_the_help_overlay_fits_small_windows(window):
    # At 14 px the 28 rows of keys (20 px each) were cut off in windows under about 590 pixels high.
    from rayvr.app.hud import MARGIN, font_size_for, help_layout

    place = help_layout(window, KEYS, font_size_for(window, 14), _atlas_measure)
    x, y, w, h = place.box
    assert place.fits and MARGIN <= x and x + w <= window[0] - MARGIN and MARGIN <= y and y + h <= window[1] - MARGIN
    assert place.columns * place.rows >= len(KEYS) + 1  # every key, and the title
    line_height, width = _atlas_measure(place.font_size)
    assert all(width(k) < place.key_width for k, _ in KEYS)  # a key never runs into its description
    assert h >= place.rows * line_height


def test_the_hud_font_follows_the_window_down_to_a_floor():
    from rayvr.app.hud import MIN_FONT_SIZE, font_size_for

    assert font_size_for((1920, 1080), 14) == font_size_for((1280, 720), 14) == 14
    assert font_size_for((640, 360), 14) == 7 and font_size_for((1280, 360), 14) == 7  # the tighter side
    assert font_size_for((100, 60), 14) == MIN_FONT_SIZE
    assert font_size_for((640, 360), 28) == 14  # a high-DPI screen's doubled font, halved


def _window_hud_share(size):
    """The share of the window the HUD panel covers after one frame, and the help overlay's layout."""
    from rayvr.app.hud import PAD, help_layout

    p = _preview(size=size, hud=True, materials="rayvr/assets/default_room.toml")
    try:
        p.frame()
        lines = [t for t, _ in p.hud_lines(p.last_layout, size)]
        w = max(p.hud.width(t) for t in lines) + 2 * PAD
        h = len(lines) * p.hud.line_height + 2 * PAD
        place = help_layout(size, KEYS, p.hud.font_size, p.hud.measure)
        return w * h / (size[0] * size[1]), place.fits
    finally:
        p.close()


def test_the_hud_covers_a_small_share_of_a_small_window(worker):
    share, help_fits = worker(_window_hud_share, (640, 360))
    assert share < 0.25, share  # at 14 px it covered about half of it
    assert help_fits


def _budget_mode():
    """The preview in budget mode with the measuring stubbed (it is tested in test_frame_budget.py):
    how often it picks, and what its HUD says."""
    import glfw

    from rayvr.app import budget_keeper
    from rayvr.quality import frame_budget
    from rayvr.scene.materials import MaterialConfig

    calls = []

    def fake(renderer, rig, budget_ms, **kw):
        calls.append(budget_ms)
        return MaterialConfig(default="shadows"), {"budget_ms": budget_ms, "within_budget": True, "feasible": True,
                                                   "predicted_ms": 9.0, "measured_ms": 9.5, "measured_flip": 0.04,
                                                   "assignment": {"floor": "shadows"}}

    frame_budget.auto_config = fake
    budget_keeper.SETTLE_S = 0.0
    p = _preview(size=(64, 24), hud=True)
    try:
        out = {}
        _press(p, glfw.KEY_K)
        p.frame()
        out["without"] = (len(calls), p.message)
        p.apply_budget(1000 / 90)
        p.frame()
        p.frame()  # the view has not changed: no pick
        out["start"] = (len(calls), [t for t, _ in p.hud_lines(p.last_layout, (64, 24))])
        _press(p, glfw.KEY_K)
        p.frame()
        out["key"] = len(calls)
        p.camera.move(0.0, 0.0, 1.0, 0.5 * p.renderer.scene.extent / p.camera.speed)  # half the scene away
        p.frame()
        p.frame()
        out["moved"] = len(calls)
        out["default"] = p.renderer.config.default
        return out
    finally:
        p.close()


def test_budget_mode_picks_at_start_on_k_and_when_the_view_changes(worker):
    out = worker(_budget_mode)
    assert out["without"][0] == 0 and "budget mode" in out["without"][1]
    count, hud = out["start"]
    assert count == 1
    assert "budget 11.11 ms (90 Hz): within, measured 9.50 ms" in " ".join(hud), hud  # (lines wrap at spaces)
    assert out["key"] == 2
    assert out["moved"] == 3  # moved and settled (SETTLE_S 0 here): one pick, not one per frame
    assert out["default"] == "shadows"  # the pick renders


def test_a_refused_first_config_says_what_renders_instead_and_file_writes_reach_the_terminal(tmp_path, caplog, capsys):
    """Issue 46 item 8: a first config that does not load keeps no "previous" one (every material
    renders raster until it loads); a refused config after a good one keeps that one. A message that
    names files written (a screenshot, a camera path) is printed, not only shown on the HUD."""
    import logging
    from types import SimpleNamespace

    from rayvr.app.preview import Preview

    bad = tmp_path / "bad.toml"
    bad.write_text('default = "warp9"\n')
    state = SimpleNamespace(materials_path=bad, _config_stamp=None, config_error=None, config_loaded=False)
    with caplog.at_level(logging.WARNING, logger="rayvr.app.preview"):
        assert Preview.poll_config(state, force=True)
    assert "every material raster until the file loads" in caplog.text and "previous" not in caplog.text
    caplog.clear()
    state.config_loaded = True
    with caplog.at_level(logging.WARNING, logger="rayvr.app.preview"):
        assert Preview.poll_config(state, force=True)
    assert "keeping the previous material config" in caplog.text
    Preview.say(state, "screenshot: out/preview_0001_* (3 files)", wrote=True)
    Preview.say(state, "stereo: warp")
    printed = capsys.readouterr().out
    assert "rayvr preview: screenshot: out/preview_0001_* (3 files)" in printed and "stereo" not in printed
    assert state.message == "stereo: warp"


def test_the_hud_covers_at_most_a_third_of_a_small_window_keeping_what_matters():
    """Issue 46 item 8: at small sizes the HUD covered two thirds of the window. It is cut to a third:
    the frame time first, the coloured lines (an error, a message) kept before the plain ones, and a last
    line that says how many were left out; a tall window shows everything."""
    from rayvr.app.preview import hud_fitted

    white, red, dim = (1, 1, 1, 1), (1, 0.35, 0.3, 1), (0.7, 0.7, 0.7, 1)
    lines = [("12.0 ms/frame", white)] + [(f"info {i}", white) for i in range(6)] + \
        [("config error: warp9", red), ("H: help", dim)]
    assert hud_fitted(lines, 1000, 14) == lines
    small = hud_fitted(lines, 90, 14)  # 30 px: two lines' room, at least the first and the help line
    assert [t for t, _ in small] == ["12.0 ms/frame", "H: help   (7 lines more in a larger window)"]
    mid = hud_fitted(lines, 180, 14)  # 60 px: four lines
    assert [t for t, _ in mid] == ["12.0 ms/frame", "info 0", "config error: warp9",  # kept in their order
                                   "H: help   (5 lines more in a larger window)"]
    assert len(mid) * 14 <= 180 / 3 + 14
