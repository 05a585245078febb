"""Desktop stereo preview: a glfw window that shows both eyes, moves with mouse and keys, shows
per-pass GPU timings, and reloads the material config when its file changes.

    python app.py [SCENE] [--materials FILE]        # or: rayvr preview ...

Three layers, so the input handling is testable without a window:
- `Camera`: fly and orbit navigation, IPD and convergence; builds the `StereoRig` of each frame.
- `Controls`: the input state machine. Key names ("W", "TAB", "F12", as glfw spells them without
  `KEY_`), mouse buttons, cursor and wheel go in; `ViewState` changes and requested actions
  (screenshot, reload, ...) come out. No GL, no glfw.
- `Preview`: the window. glfw callbacks translate events for `Controls`; `frame()` records the
  renderer's passes, draws the eye images (side by side, cross-eyed, anaglyph, one eye), picks
  the material under the cursor, draws the HUD and swaps.
"""
from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from ..scene import materials as materials_mod
from ..gl import shaders
from ..frame.accumulation import temporal_problem
from ..render_options.denoise import MAX_DENOISE_ITERATIONS
from ..frame.cameras.rig import Pose, StereoRig, save_path
from .viewpoint import first_rig
from ..frame.gbuffer import NO_HIT
from ..frame.passes import primary_rays

log = logging.getLogger(__name__)

STEREO_MODES = ("side-by-side", "cross-eyed", "anaglyph", "left", "right")
RES_SCALES = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0)
LOOK_RADIANS_PER_PIXEL = 0.004
MAX_PITCH = math.radians(89.0)
RECORD_FPS = 30.0  # camera paths are sampled at a fixed rate so replays keep the pace
MESSAGE_SECONDS = 4.0
# T steps the `ssr` quadtree thresholds through these (label, gamma_norm as a cosine, gamma_dist)
QUADTREE_PRESETS = (("lossless", 1.0, 0.0), ("3 deg, 1e-5", math.cos(math.radians(3)), 1e-5),
                    ("10 deg, 1e-3", math.cos(math.radians(10)), 1e-3), ("25 deg, 1e-1", math.cos(math.radians(25)), 0.1))
EYE_UNIT, ATLAS_UNIT = 8, 9  # texture units clear of the G-buffer's 0..6
PICK_BINDING = 7  # SSBO binding clear of the scene's 0..4 and the BVH's 8..

# The keys, in the order the help overlay and docs/usage.md list them.
KEYS = (
    ("W A S D", "fly forward / left / back / right (orbit: nearer, turn, farther, turn)"),
    ("Q E", "fly down / up (orbit: tilt)"),
    ("Shift, Ctrl", "hold: move 4x faster, 4x slower"),
    ("left drag", "look around (orbit: turn around the scene centre)"),
    ("wheel", "fly speed (orbit: distance)"),
    ("F", "fly <-> orbit around the scene centre"),
    ("R", "reset camera, IPD and convergence"),
    ("Tab, 1-5", "stereo mode: side-by-side, cross-eyed, anaglyph, left, right"),
    ("B, Shift+B", "how the second eye is made: dual, warp, reuse (next / previous)"),
    ("V, Shift+V", "next / previous view: colour, then each debug view"),
    ("- =", "IPD smaller / larger"),
    ("C", "convergence at the scene centre / parallel eyes"),
    ("[ ]", "convergence nearer / farther"),
    ("O, Shift+O", "global effect override: next / previous (off = the config file)"),
    ("T", "ssr quadtree thresholds: next preset"),
    ("M", "accumulate samples while still on / off (any change starts over)"),
    ("N", "denoiser on / off (the config's `denoise` effects)"),
    ("I, Shift+I", "denoiser iterations more / fewer"),
    ("G", "temporal reprojection on / off (a move keeps what stays visible)"),
    (", .", "resolution scale down / up"),
    ("Y", "vsync on / off"),
    ("P", "record a camera path on / off (saved on stop; rayvr capture --path)"),
    ("F12", "screenshot: the files rayvr capture writes, plus the window"),
    ("L", "reload the material config now"),
    ("K", "budget mode: pick effects for this view now (it does when the view has changed)"),
    ("F2", "HUD on / off"),
    ("H, F1", "this help"),
    ("Esc", "quit"),
)


# ------------------------------------------------------------------------------- camera

def _yaw_pitch(rotation) -> tuple[float, float]:
    f = -np.asarray(rotation, float)[:, 2]
    return math.atan2(-f[0], -f[2]), math.asin(float(np.clip(f[1], -1.0, 1.0)))


def _forward(yaw: float, pitch: float) -> np.ndarray:
    """Unit view direction; yaw 0 pitch 0 looks down -Z, positive yaw turns left."""
    return np.array([-math.sin(yaw) * math.cos(pitch), math.sin(pitch), -math.cos(yaw) * math.cos(pitch)])


class Camera:
    """Head pose by fly or orbit navigation, plus the rig's IPD and convergence.

    Orientation is yaw and pitch (no roll), so the horizon stays level however the mouse moves.
    In orbit mode the eye sits at `distance` from `center`, looking at it."""

    def __init__(self, rig: StereoRig, center, extent: float):
        self.home = rig
        self.center = np.asarray(center, dtype=np.float64)
        self.extent = max(float(extent), 1e-6)
        self.reset()

    def reset(self) -> None:
        rig = self.home
        self.mode = "fly"
        self.position = np.array(rig.pose.position, dtype=np.float64)
        self.yaw, self.pitch = _yaw_pitch(rig.pose.rotation)
        self.ipd, self.convergence = rig.ipd, rig.convergence
        # scene units per second: a tenth of the scene's diagonal, about a walk (1.2 m/s) in the room;
        # a quarter crossed the room in 2 s (the wheel changes it)
        self.speed = self.extent * 0.1
        self.distance = max(float(np.linalg.norm(self.position - self.center)), self.extent * 1e-3)

    @property
    def forward(self) -> np.ndarray:
        return _forward(self.yaw, self.pitch)

    @property
    def pose(self) -> Pose:
        f = self.forward
        up = (0.0, 1.0, 0.0) if abs(f[1]) < 0.999 else (0.0, 0.0, -1.0)
        return Pose.look_at(self.position, self.position + f, up)

    def rig(self, size) -> StereoRig:
        return replace(self.home, pose=self.pose, ipd=self.ipd, convergence=self.convergence, size=tuple(size))

    def set_mode(self, mode: str) -> None:
        if mode == "orbit" and self.mode != "orbit":
            # Keep the eye where it is and turn it towards the centre.
            offset = self.center - self.position
            self.distance = max(float(np.linalg.norm(offset)), self.extent * 1e-3)
            if np.linalg.norm(offset) > 0:
                f = offset / np.linalg.norm(offset)
                self.yaw, self.pitch = math.atan2(-f[0], -f[2]), math.asin(float(np.clip(f[1], -1, 1)))
            self._place_orbit()
        self.mode = mode

    def _place_orbit(self) -> None:
        self.position = self.center - self.forward * self.distance

    def look(self, dx: float, dy: float) -> None:
        """Turn by a mouse movement in pixels (right and down positive)."""
        self.yaw -= dx * LOOK_RADIANS_PER_PIXEL
        self.pitch = float(np.clip(self.pitch - dy * LOOK_RADIANS_PER_PIXEL, -MAX_PITCH, MAX_PITCH))
        if self.mode == "orbit":
            self._place_orbit()

    def move(self, right: float, up: float, forward: float, dt: float) -> None:
        """Held keys: each axis in -1..1 (times a speed factor), for `dt` seconds."""
        if self.mode == "fly":
            f = self.forward
            r = np.cross(f, [0.0, 1.0, 0.0])
            r = r / np.linalg.norm(r) if np.linalg.norm(r) > 1e-9 else np.array([1.0, 0.0, 0.0])
            step = (forward * f + right * r + up * np.array([0.0, 1.0, 0.0])) * self.speed * dt
            self.position = self.position + step
        else:  # orbit: forward = nearer, right = turn, up = tilt
            self.distance = max(self.distance * math.exp(-forward * dt), self.extent * 1e-4)
            self.yaw += right * dt
            self.pitch = float(np.clip(self.pitch - up * dt, -MAX_PITCH, MAX_PITCH))
            self._place_orbit()

    def wheel(self, steps: float) -> None:
        if self.mode == "fly":
            self.speed = float(np.clip(self.speed * 1.25 ** steps, self.extent * 1e-4, self.extent * 100))
        else:
            self.distance = max(self.distance * 0.9 ** steps, self.extent * 1e-4)
            self._place_orbit()

    def scale_ipd(self, factor: float) -> None:
        floor = max(self.home.ipd, 1e-3) / 16  # below this, stepping down means "no stereo"
        if factor < 1:
            self.ipd = 0.0 if self.ipd * factor < floor else self.ipd * factor
        else:
            self.ipd = floor if self.ipd == 0 else self.ipd * factor

    def toggle_convergence(self) -> None:
        self.convergence = None if self.convergence else max(
            float(np.linalg.norm(self.center - self.position)), self.extent * 1e-3)

    def scale_convergence(self, factor: float) -> None:
        if self.convergence:
            self.convergence *= factor


# ---------------------------------------------------------------------------- controls

@dataclass
class ViewState:
    """What the window shows; changed only by `Controls`."""

    stereo: str = "side-by-side"
    method: str = "dual"  # how the second eye is made (rayvr/frame/stereo.py STEREO_MODES)
    view: str = "color"
    res_scale: float = 1.0
    vsync: bool = True
    hud: bool = True
    help: bool = False
    override: str | None = None  # effect forced on every material; None = the config file
    accumulate: bool = True  # samples add up while the view is still (rayvr/frame/accumulation.py)
    denoise: bool = False
    denoise_iterations: int = 4
    temporal: bool = False
    recording: bool = False
    quit: bool = False


@dataclass
class Controls:
    """Input state machine: events in; `state` and `camera` change, and requests that need the
    window or the disk are queued in `actions` for the window loop ("screenshot", "reload",
    "vsync", "record", "quadtree")."""

    camera: Camera
    state: ViewState = field(default_factory=ViewState)
    views: tuple = ()
    effects: tuple = ()  # what the override cycles through (implemented effects only)
    actions: list = field(default_factory=list)
    held: set = field(default_factory=set)
    cursor_pos: tuple | None = None  # framebuffer pixels, origin top-left
    dragging: bool = False

    def __post_init__(self):
        if not self.views:
            from ..gl.gpu_layout import VIEWS
            self.views = VIEWS
        if not self.effects:
            self.effects = tuple(materials_mod.implemented_effects())

    def take_actions(self) -> list:
        out, self.actions = self.actions, []
        return out

    def key(self, name: str, action: str = "press", shift: bool = False, ctrl: bool = False) -> None:
        """`action` is "press", "repeat" or "release"; held movement keys are applied by `update`."""
        if action == "release":
            self.held.discard(name)
            return
        self.held.add(name)
        s, cam = self.state, self.camera
        step = -1 if shift else 1
        if name in ("TAB", "1", "2", "3", "4", "5"):
            i = STEREO_MODES.index(s.stereo)
            i = (i + step) % len(STEREO_MODES) if name == "TAB" else int(name) - 1
            s.stereo = STEREO_MODES[i]
        elif name == "B":
            from ..frame.stereo import STEREO_MODES as methods
            s.method = methods[(methods.index(s.method) + step) % len(methods)]
        elif name == "V":
            s.view = self.views[(self.views.index(s.view) + step) % len(self.views)]
        elif name == "O":
            cycle = (None,) + tuple(self.effects)
            s.override = cycle[(cycle.index(s.override) + step) % len(cycle)]
        elif name in ("COMMA", "PERIOD"):
            i = min(range(len(RES_SCALES)), key=lambda k: abs(RES_SCALES[k] - s.res_scale))
            i = max(0, min(len(RES_SCALES) - 1, i + (1 if name == "PERIOD" else -1)))
            s.res_scale = RES_SCALES[i]
        elif name == "MINUS":
            cam.scale_ipd(1 / 1.25)
        elif name == "EQUAL":
            cam.scale_ipd(1.25)
        elif name == "C" and action == "press":
            cam.toggle_convergence()
        elif name == "LEFT_BRACKET":
            cam.scale_convergence(1 / 1.25)
        elif name == "RIGHT_BRACKET":
            cam.scale_convergence(1.25)
        elif action != "press":
            return  # the rest are toggles: auto-repeat must not flip them back and forth
        elif name == "F":
            cam.set_mode("orbit" if cam.mode == "fly" else "fly")
        elif name == "R":
            cam.reset()
        elif name == "Y":
            s.vsync = not s.vsync
            self.actions.append("vsync")
        elif name == "P":
            s.recording = not s.recording
            self.actions.append("record")
        elif name == "T":
            self.actions.append("quadtree")
        elif name == "M":
            s.accumulate = not s.accumulate
        elif name == "N":
            s.denoise = not s.denoise
        elif name == "I":
            s.denoise_iterations = max(1, min(MAX_DENOISE_ITERATIONS, s.denoise_iterations + step))
        elif name == "G":
            s.temporal = not s.temporal
        elif name == "F12":
            self.actions.append("screenshot")
        elif name == "L":
            self.actions.append("reload")
        elif name == "K":
            self.actions.append("repick")
        elif name == "F2":
            s.hud = not s.hud
        elif name in ("H", "F1"):
            s.help = not s.help
        elif name == "ESCAPE":
            if s.help:
                s.help = False
            else:
                s.quit = True

    def mouse_button(self, button: str, pressed: bool) -> None:
        if button == "left":
            self.dragging = pressed

    def cursor(self, x: float, y: float) -> None:
        if self.dragging and self.cursor_pos is not None:
            self.camera.look(x - self.cursor_pos[0], y - self.cursor_pos[1])
        self.cursor_pos = (x, y)

    def scroll(self, steps: float) -> None:
        self.camera.wheel(steps)

    def update(self, dt: float) -> None:
        """Apply held movement keys for `dt` seconds."""
        h = self.held
        axis = lambda neg, pos: float(pos in h) - float(neg in h)  # noqa: E731
        right, up, forward = axis("A", "D"), axis("Q", "E"), axis("S", "W")
        if right or up or forward:
            factor = 1.0
            if h & {"LEFT_SHIFT", "RIGHT_SHIFT"}:
                factor *= 4.0
            if h & {"LEFT_CONTROL", "RIGHT_CONTROL"}:
                factor /= 4.0
            self.camera.move(right * factor, up * factor, forward * factor, dt)


# ------------------------------------------------------------------------------ layout

@dataclass
class Layout:
    """How the eyes fill a framebuffer: what to render and where each layer goes."""

    eyes: str  # what Renderer.record renders: both | left | right
    eye_size: tuple  # per-eye render size (after the resolution scale)
    viewports: list  # (x, y, w, h, layer), GL bottom-up pixels
    anaglyph: bool = False

    def texel_at(self, x: float, y: float, fb_height: int):
        """The (x, y, layer) eye texel (GL bottom-up rows) under framebuffer pixel (x, y)
        counted from the top-left, or None outside every viewport."""
        gy = fb_height - y  # cursor y in [0, H) from the top -> (0, H] from the bottom
        for vx, vy, vw, vh, layer in self.viewports:
            if vx <= x < vx + vw and vy < gy <= vy + vh:
                tx = int((x - vx) / vw * self.eye_size[0])
                ty = int((gy - vy) / vh * self.eye_size[1])
                return (min(tx, self.eye_size[0] - 1), min(ty, self.eye_size[1] - 1), layer)
        return None


def layout_for(stereo: str, fb_size, scale: float = 1.0) -> Layout:
    w, h = int(fb_size[0]), int(fb_size[1])
    scaled = lambda vw, vh: (max(1, round(vw * scale)), max(1, round(vh * scale)))  # noqa: E731
    if stereo in ("side-by-side", "cross-eyed"):
        half = w // 2
        left, right = (0, 0, half, h), (half, 0, w - half, h)
        first, second = (0, 1) if stereo == "side-by-side" else (1, 0)  # layer 0 = left eye
        return Layout("both", scaled(half, h), [(*left, first), (*right, second)])
    if stereo == "anaglyph":
        return Layout("both", scaled(w, h), [(0, 0, w, h, 0)], anaglyph=True)
    if stereo in ("left", "right"):
        return Layout(stereo, scaled(w, h), [(0, 0, w, h, 0)])
    raise ValueError(f"unknown stereo mode {stereo!r}; allowed: {', '.join(STEREO_MODES)}")


def _glfw_key_names() -> dict:
    import glfw

    return {getattr(glfw, n): n[4:] for n in dir(glfw) if n.startswith("KEY_") and n != "KEY_UNKNOWN"}


def _wrap(text: str, width_px: int, measure) -> list[str]:
    """Greedy word wrap by measured pixel width (the HUD font is proportional)."""
    lines = []
    for para in text.splitlines() or [""]:
        line = ""
        for word in para.split(" "):
            cand = f"{line} {word}" if line else word
            if line and measure(cand) > width_px:
                lines.append(line)
                line = word
            else:
                line = cand
        lines.append(line)
    return lines


# ------------------------------------------------------------------------------ window

HUD_SHARE = 1 / 3  # of the window's height the HUD panel may cover; a help line tells what is cut
HUD_WHITE = (1, 1, 1, 1)  # the HUD's plain lines; the coloured ones (errors, messages) are kept first when cut


def hud_fitted(lines: list, height: int, line_height: int) -> list:
    """`lines` ((text, rgba) each, first the frame time, last "H: help") cut to HUD_SHARE of a window
    `height` pixels tall: the first line, the coloured ones (errors, recording, messages, the budget)
    and as many of the others as fit, in their order; the last line says how many were left out."""
    fits = max(2, int(height * HUD_SHARE) // max(int(line_height), 1))
    if len(lines) <= fits:
        return lines
    body = lines[1:-1]
    ranked = sorted(range(len(body)), key=lambda i: (tuple(body[i][1]) == HUD_WHITE, i))
    keep = sorted(ranked[:max(fits - 2, 0)])
    cut = len(body) - len(keep)
    return [lines[0], *[body[i] for i in keep], (f"H: help   ({cut} lines more in a larger window)", lines[-1][1])]


class Preview:
    """The preview window around a `Renderer`. `run()` loops until the window closes;
    `frame()` renders one frame (tests drive it directly)."""

    def __init__(self, scene=None, materials=None, *, size=(1280, 720), title=None, visible=True,
                 vsync=True, stereo="side-by-side", view="color", res_scale=None, rig=None,
                 rig_options=None, look_at=None, out_dir="shots", path_file="camera_path.json", hud=True,
                 stereo_method="dual", dof=None, seed=0, settings=None):
        """`dof`: (lens diameter, focus distance, samples) of the thin-lens depth of field (frame/passes/dof.py);
        `settings`: the RenderSettings to start from (the denoiser and --temporal: the keys' state at start)."""
        from ..gl.context import create_window_context, import_glfw
        from ..renderer import Renderer

        if stereo not in STEREO_MODES:
            raise ValueError(f"unknown stereo mode {stereo!r}; allowed: {', '.join(STEREO_MODES)}")
        from ..frame.stereo import check_mode

        check_mode(stereo_method)
        if res_scale is not None and not (0 < res_scale <= 4):
            raise ValueError(f"resolution scale must be in (0, 4], got {res_scale}")
        self.glfw = import_glfw()
        self.window, self.gl = create_window_context(size, title or "rayvr preview", visible, vsync)
        try:
            # Start from the built-in all-`raster` config; the file is applied below so that a bad
            # file opens the window with the error in the HUD instead of failing.
            from ..renderer import RenderSettings

            self.renderer = Renderer(scene, None, gl=self.gl, settings=replace(settings or RenderSettings(), seed=seed))
            if dof is not None:
                self.renderer.settings = replace(self.renderer.settings, dof_diameter=dof[0], dof_focus=dof[1],
                                                 dof_samples=dof[2])
            ctx = self.ctx = self.gl.ctx
            self.home_rig = rig or (first_rig(self.renderer.scene, size, **(rig_options or {})) if look_at is None
                                    else StereoRig.for_scene(self.renderer.scene, size=size, **(rig_options or {})))
            if look_at is not None:  # (eye, target)
                self.home_rig = replace(self.home_rig, pose=Pose.look_at(*look_at))
            self.camera = Camera(self.home_rig, self.renderer.scene.center, self.renderer.scene.extent)
            gl_name = ctx.info.get("GL_RENDERER", "")
            if res_scale is None:  # a CPU rasterizer is slow: start at half resolution there
                res_scale = 0.5 if ("llvmpipe" in gl_name or "softpipe" in gl_name) else 1.0
            st = self.renderer.settings
            state = ViewState(stereo=stereo, method=stereo_method, view=view, res_scale=res_scale, vsync=vsync, hud=hud,
                              denoise=st.denoise, denoise_iterations=st.denoise_iterations, temporal=st.temporal)
            self.controls = Controls(self.camera, state)
            self.gl_name = gl_name
            self.scene_name = str(scene) if isinstance(scene, (str, Path)) else self.renderer.scene.name
            self._init_gl()
        except BaseException:
            self.gl.release()
            raise
        self.materials_path = Path(materials) if materials else None
        self.file_config = materials_mod.MaterialConfig()  # every material raster until a config loads
        self.config_loaded = False  # whether a config file has loaded (a refused one then keeps it)
        self.quadtree_preset = 0
        self.config_error: str | None = None
        self._config_stamp = None
        self.out_dir, self.path_file = Path(out_dir), Path(path_file)
        self.message, self._message_until = "", 0.0
        self.recorded: list[Pose] | None = None
        self._record_clock = 0.0
        self.picked = None  # (material index, effect id) under the cursor
        self.budget_keeper = None  # budget mode (--budget-ms): picks effects again as the view changes
        self.timings: dict = {}  # pass -> smoothed GPU ms
        self.frame_ms = 0.0
        self.frames = 0
        self.screenshots = 0
        self.last_files: list[Path] = []
        self.last_frame = self.last_layout = None  # the newest frame's FrameContext and Layout
        self._last_time = time.perf_counter()
        self._applied_override = None
        self._good = (None, None)  # the last (config, override) that rendered
        if self.materials_path is not None:
            self.poll_config(force=True)
        self._install_callbacks()

    @property
    def state(self) -> ViewState:
        return self.controls.state

    def _init_gl(self) -> None:
        ctx = self.ctx
        self.eye_program = shaders.program(ctx, "preview/fullscreen.vert", "preview/eyes.frag")
        self.eye_vao = ctx.vertex_array(self.eye_program, [])
        self.sampler = ctx.sampler(repeat_x=False, repeat_y=False)
        self.pick_program = shaders.compute(ctx, "preview/pick.comp")
        self.pick_buffer = ctx.buffer(reserve=8)
        from .hud import Hud

        scale = max(self.glfw.get_window_content_scale(self.window))  # 2 on high-DPI screens
        self.hud = Hud(ctx, font_size=round(14 * max(scale, 1.0)))

    # -- glfw callbacks (tests call these with glfw constants, as glfw would) -------------
    def _install_callbacks(self) -> None:
        glfw, w = self.glfw, self.window
        self._key_names = _glfw_key_names()
        glfw.set_key_callback(w, self.on_key)
        glfw.set_mouse_button_callback(w, self.on_mouse_button)
        glfw.set_cursor_pos_callback(w, self.on_cursor_pos)
        glfw.set_scroll_callback(w, self.on_scroll)

    def on_key(self, window, key, scancode, action, mods) -> None:
        glfw = self.glfw
        name = self._key_names.get(key)
        if name is None:
            return
        kind = {glfw.PRESS: "press", glfw.REPEAT: "repeat", glfw.RELEASE: "release"}[action]
        self.controls.key(name, kind, shift=bool(mods & glfw.MOD_SHIFT), ctrl=bool(mods & glfw.MOD_CONTROL))

    def on_mouse_button(self, window, button, action, mods) -> None:
        glfw = self.glfw
        name = {glfw.MOUSE_BUTTON_LEFT: "left", glfw.MOUSE_BUTTON_RIGHT: "right",
                glfw.MOUSE_BUTTON_MIDDLE: "middle"}.get(button)
        if name:
            self.controls.mouse_button(name, action == glfw.PRESS)

    def on_cursor_pos(self, window, x, y) -> None:
        # Window coordinates -> framebuffer pixels (they differ on high-DPI screens).
        ww, wh = self.glfw.get_window_size(self.window)
        fw, fh = self.glfw.get_framebuffer_size(self.window)
        self.controls.cursor(x * fw / max(ww, 1), y * fh / max(wh, 1))

    def on_scroll(self, window, dx, dy) -> None:
        self.controls.scroll(dy)

    # -- material config ----------------------------------------------------------------
    def poll_config(self, force: bool = False) -> bool:
        """Re-read the config file when it changed on disk (or `force`); True when re-read."""
        if self.materials_path is None:
            return False
        try:
            st = os.stat(self.materials_path)
            stamp = (st.st_mtime_ns, st.st_size, st.st_ino)
        except OSError as exc:
            stamp = ("missing", exc.errno)
        if stamp == self._config_stamp and not force:
            return False
        self._config_stamp = stamp
        try:
            config = materials_mod.load_config(self.materials_path)
            config.assign(self.renderer.scene.material_names())  # warns about unmatched keys
        except materials_mod.ConfigError as exc:
            # Keep rendering with the last good config; the HUD shows why the file was refused.
            self.config_error = str(exc)
            kept = ("keeping the previous material config" if self.config_loaded
                    else "every material raster until the file loads")
            log.warning("%s (%s)", exc, kept)
            return True
        self.file_config, self.config_error, self.config_loaded = config, None, True
        self._apply_materials()
        self.say(f"material config loaded: {self.materials_path.name}")
        return True

    def apply_budget(self, budget_ms: float) -> str:
        """`--budget-ms`: measure this scene on this device from the current view, pick effects per
        material that fit the budget, and render with them (the config file's params stay the
        base); from then on pick again when the view has changed and settled (app/budget_keeper.py).
        Returns the summary the HUD and terminal show."""
        from ..quality.budget import describe_pick
        from ..quality.frame_budget import auto_config
        from .budget_keeper import BudgetKeeper

        if self.budget_keeper is None or self.budget_keeper.budget_ms != budget_ms:
            self.budget_keeper = BudgetKeeper(budget_ms, self.renderer.scene.extent)
        fb = self.glfw.get_framebuffer_size(self.window)
        rig = self.camera.rig(layout_for(self.state.stereo, fb, self.state.res_scale).eye_size)
        config, summary = auto_config(self.renderer, rig, budget_ms, progress=False)
        self.budget_keeper.picked(self.camera.pose, summary)
        self.file_config = config
        self._apply_materials()
        text = describe_pick(summary)
        self.say(text.splitlines()[0])
        return text

    def override_config(self, effect: str) -> materials_mod.MaterialConfig:
        """Every material gets `effect`, with the file's [params] for it."""
        return materials_mod.parse_config({"default": effect, "params": self.file_config.params},
                                          f"override:{effect}")

    def _apply_materials(self) -> None:
        effect = self.state.override
        self.renderer.set_materials(self.override_config(effect) if effect else self.file_config)
        self._applied_override = effect

    def cycle_quadtree_thresholds(self) -> None:
        """T: the next (gamma_norm, gamma_dist) preset for every `ssr` material (the quadtree's
        plane-merge thresholds: lossless, then coarser), until the config file is reloaded."""
        self.quadtree_preset = (self.quadtree_preset + 1) % len(QUADTREE_PRESETS)
        label, gamma_norm, gamma_dist = QUADTREE_PRESETS[self.quadtree_preset]
        self.file_config = materials_mod.config_with(
            self.file_config, params={"ssr": {"gamma_norm": gamma_norm, "gamma_dist": gamma_dist}})
        self._apply_materials()
        users = "ssr" in self.renderer.effects_in_use()
        self.say(f"quadtree thresholds: {label} (gamma_norm {gamma_norm:.4f}, gamma_dist {gamma_dist:g})"
                 + ("" if users else "; no material uses ssr (O overrides every material)"))

    # -- actions ------------------------------------------------------------------------
    def say(self, text: str, seconds: float = MESSAGE_SECONDS, wrote: bool = False) -> None:
        """Show `text` on the HUD for `seconds`; `wrote`: it names files written, so the terminal
        says it too (a screenshot or a path lands in a folder the window does not show)."""
        self.message, self._message_until = text, time.perf_counter() + seconds
        if wrote:
            print(f"rayvr preview: {text}", flush=True)
        else:
            log.info("%s", text)

    def _do(self, action: str) -> None:
        if action == "vsync":
            self.glfw.swap_interval(1 if self.state.vsync else 0)
        elif action == "reload":
            self.poll_config(force=True)
        elif action == "repick":
            if self.budget_keeper is None:
                self.say("K picks effects again in budget mode (start with --budget-ms or --budget-hz)")
            else:
                self.apply_budget(self.budget_keeper.budget_ms)
        elif action == "quadtree":
            self.cycle_quadtree_thresholds()
        elif action == "record":
            if self.state.recording:
                # A full period on the clock: the first pose is taken at the end of this frame.
                self.recorded, self._record_clock = [], 1.0 / RECORD_FPS
                self.say(f"recording a camera path to {self.path_file}")
            else:
                self.save_recording()

    def save_recording(self) -> Path | None:
        poses, self.recorded = self.recorded, None
        self.state.recording = False
        if not poses:
            return None
        save_path(self.path_file, poses, fps=RECORD_FPS, ipd=self.camera.ipd, fov_y=self.home_rig.fov_y)
        self.say(f"camera path saved: {self.path_file} ({len(poses)} poses; rayvr capture --path {self.path_file})",
                 wrote=True)
        return self.path_file

    def screenshot(self, window_image: np.ndarray | None, layout: Layout) -> list[Path]:
        """Write what `rayvr capture` writes for the current view (same code path, same file
        names, prefix `preview_NNNN`), plus the window as `<prefix>_window.png`."""
        from .capture import CaptureJob, run_capture, write_summary
        from ..util.output import write_png

        self.out_dir.mkdir(parents=True, exist_ok=True)
        while True:
            self.screenshots += 1
            prefix = f"preview_{self.screenshots:04d}"
            if not any(self.out_dir.glob(prefix + "_*")):
                break
        rig = self.camera.rig(layout.eye_size)
        job = CaptureJob(rig, [rig.pose], layout.eyes, self.state.view, (), self.out_dir, prefix)
        summary = run_capture(self.renderer, job, progress=False)
        files = [Path(f) for f in summary["files"]] + [write_summary(job, summary)]
        if window_image is not None:
            p = self.out_dir / f"{prefix}_window.png"
            write_png(p, window_image)
            files.append(p)
        self.last_files = files
        self.say(f"screenshot: {self.out_dir}/{prefix}_* ({len(files)} files)", wrote=True)
        return files

    # -- the frame ----------------------------------------------------------------------
    def frame(self, grab: bool = False) -> np.ndarray | None:
        """Handle input, render, draw and swap one frame. With `grab`, return the window as
        (H, W, 3) uint8, rows top-down, read back before the swap."""
        now = time.perf_counter()
        dt, self._last_time = now - self._last_time, now
        self.frame_ms += ((dt * 1000.0) - self.frame_ms) * (0.1 if self.frames > 2 else 1.0)
        self.controls.update(min(dt, 0.1))  # a stalled frame must not throw the camera away
        self.poll_config()
        actions = self.controls.take_actions()
        for a in actions:
            if a != "screenshot":
                self._do(a)
        if self.budget_keeper is not None and "repick" not in actions and self.budget_keeper.due(self.camera.pose, now):
            self.apply_budget(self.budget_keeper.budget_ms)  # the view changed and settled: a pick for it
        if self.state.override != self._applied_override:
            self._apply_materials()
        fb = self.glfw.get_framebuffer_size(self.window)
        if fb[0] < 1 or fb[1] < 1:  # minimized
            return None
        layout = layout_for(self.state.stereo, fb, self.state.res_scale)
        rig = self.camera.rig(layout.eye_size)
        problem = temporal_problem(rig.camera) if self.state.temporal else None
        if problem:  # G on a camera without planar frusta (Renderer.plan refuses temporal reprojection there)
            self.config_error = f"{problem}: G leaves it off"
            self.state.temporal = False
        self._apply_noise_settings()
        if self.state.method != "dual" and self.renderer.settings.dof_diameter > 0:
            # depth of field blurs each eye's own frame (Renderer.plan refuses warp and reuse with it)
            self.config_error = "depth of field (--dof-diameter) blurs each eye's own frame: the second eye stays dual"
            self.state.method = "dual"
        self.renderer.set_stereo(self.state.method)
        try:
            fc = self.renderer.record(rig, layout.eyes, self.state.view)
        except Exception as exc:
            if self.renderer.config is self._good[0]:
                raise
            # A new config or override the passes cannot render (say, a pass that fails to
            # build): back to the last config that rendered, with the reason in the HUD.
            self.config_error = f"{self.renderer.config.source}: rendering failed, reverted: {exc}"
            log.warning("%s", self.config_error)
            self.renderer.set_materials(self._good[0])
            self.state.override = self._applied_override = self._good[1]
            fc = self.renderer.record(rig, layout.eyes, self.state.view)
        self._good = (self.renderer.config, self.state.override)
        self.last_frame, self.last_layout = fc, layout
        self._draw_eyes(fc, layout, fb)
        self._pick(fc, layout, fb)
        if self.state.hud or self.state.help:
            self._draw_hud(layout, fb)
        image = None
        if grab or "screenshot" in actions:
            image = np.frombuffer(self.ctx.screen.read(components=3), np.uint8).reshape(fb[1], fb[0], 3)[::-1].copy()
        self.glfw.swap_buffers(self.window)
        new = self.renderer.read_ms(fc)
        a = 0.1 if self.frames > 2 else 1.0
        # Smoothed for reading; passes that no longer run (another view) drop out.
        self.timings = {k: self.timings.get(k, v) + (v - self.timings.get(k, v)) * a for k, v in new.items()}
        if self.recorded is not None:
            self._record_clock += dt
            if self._record_clock >= 1.0 / RECORD_FPS:
                self._record_clock %= 1.0 / RECORD_FPS
                self.recorded.append(self.camera.pose)
        if "screenshot" in actions:
            self.screenshot(image, layout)
        self.frames += 1
        return image

    def _apply_noise_settings(self) -> None:
        """The keys' accumulation and denoiser state into the renderer's settings (a change
        there starts the accumulation over)."""
        s, st = self.state, self.renderer.settings
        want = replace(st, accumulate=s.accumulate, denoise=s.denoise, denoise_iterations=s.denoise_iterations,
                       temporal=s.temporal)
        if want != st:
            self.renderer.settings = want

    def _draw_eyes(self, fc, layout: Layout, fb) -> None:
        ctx = self.ctx
        ctx.screen.use()
        ctx.viewport = (0, 0, fb[0], fb[1])
        ctx.clear(0.0, 0.0, 0.0, 1.0)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        tex = fc.resource(fc.plan.output)  # the warped eyes under stereo warp
        vw, vh = layout.viewports[0][2:4]
        exact = tuple(layout.eye_size) == (vw, vh)  # 1:1 pixels: no filtering, exactly the capture
        f = moderngl.NEAREST if exact else moderngl.LINEAR
        self.sampler.filter = (f, f)
        tex.use(EYE_UNIT)
        self.sampler.use(EYE_UNIT)
        self.eye_program["eyes"].value = EYE_UNIT
        self.eye_program["anaglyph"].value = int(layout.anaglyph)
        for x, y, w, h, layer in layout.viewports:
            ctx.viewport = (x, y, w, h)
            self.eye_program["layer"].value = layer
            self.eye_vao.render(moderngl.TRIANGLES, vertices=3)
        self.sampler.clear(EYE_UNIT)  # sampler objects override texture state for later passes
        ctx.viewport = (0, 0, fb[0], fb[1])

    def _pick(self, fc, layout: Layout, fb) -> None:
        pos = self.controls.cursor_pos
        texel = layout.texel_at(pos[0], pos[1], fb[1]) if pos is not None else None
        if texel is None:
            self.picked = None
            return
        fc.gbuffer.textures["material"].use(5)
        self.pick_buffer.bind_to_storage_buffer(PICK_BINDING)
        self.pick_program["texel"].value = (*texel[:2], min(texel[2], fc.gbuffer.layers - 1))  # warp: the central view
        self.pick_program.run(1, 1, 1)
        self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
        self.picked = tuple(int(v) for v in np.frombuffer(self.pick_buffer.read(), np.uint32))

    def picked_text(self) -> str:
        if self.picked is None:
            return "cursor: -"
        index, effect_id = self.picked
        if index == NO_HIT:
            return "cursor: background"
        names = self.renderer.scene.material_names()
        name = names[index] if index < len(names) else f"#{index}"
        effect = materials_mod.effect_by_id(effect_id)
        rule = self.renderer.assignments[index].rule if index < len(self.renderer.assignments) else "?"
        return f"cursor: {name} (#{index}) -> {effect.name if effect else effect_id}  [{rule}]"

    def hud_lines(self, layout: Layout, fb) -> list:
        """The HUD text, (text, rgba) per line, wrapped to the window (hud.text_width_for)."""
        from .hud import text_width_for

        s, cam = self.state, self.camera
        white, dim, red, yellow = HUD_WHITE, (0.7, 0.7, 0.7, 1), (1, 0.35, 0.3, 1), (1, 0.85, 0.3, 1)
        fps = 1000.0 / self.frame_ms if self.frame_ms > 0 else 0.0
        lines = [(f"{self.frame_ms:6.1f} ms/frame  {fps:5.1f} fps   {self.gl_name}", white)]
        gpu = "  ".join(f"{k} {v:.2f}" for k, v in self.timings.items())
        lines.append((f"GPU ms  {gpu}   total {sum(self.timings.values()):.2f}", white))
        ew, eh = layout.eye_size
        lines.append((f"{s.stereo}  view {s.view}   eye {ew}x{eh} (scale {s.res_scale:g})  window "
                      f"{fb[0]}x{fb[1]}  vsync {'on' if s.vsync else 'off'}   second eye: {s.method}", white))
        conv = f"{cam.convergence:.3g}" if cam.convergence else "parallel"
        speed = f"speed {cam.speed:.3g}/s" if cam.mode == "fly" else f"distance {cam.distance:.3g}"
        st = self.renderer.settings
        aa = f"{st.msaa}x {'ssaa' if st.ssaa else 'msaa'}" if st.msaa > 1 else "no anti-aliasing"
        aa += ", tile culling" if primary_rays.culls_tiles(st, cam.home.camera.name) else ""
        lines.append((f"{cam.mode}  {speed}   IPD {cam.ipd:.4g}  convergence {conv}   "
                      f"camera {cam.home.camera.name}, {aa}", white))
        lines.append((self.picked_text(), white))
        on = lambda b: "on" if b else "off"  # noqa: E731
        accumulating = self.last_frame is not None and self.last_frame.plan.accumulate  # (debug views do not)
        samples = self.renderer.accumulator.sample + 1 if accumulating else 1
        denoise = f"{s.denoise_iterations} iterations" if s.denoise else "off"
        lines.append((f"samples {samples}  (M accumulate {on(s.accumulate)}, G temporal {on(s.temporal)})   "
                      f"N denoise {denoise}", white))
        src = self.materials_path.name if self.materials_path else "built-in (all raster)"
        if s.override:
            lines.append((f"effect override: {s.override} on every material   (O: next; off: back to {src})", yellow))
        else:
            lines.append((f"effects from config: {src}", white))
        if self.budget_keeper is not None:
            lines.append((self.budget_keeper.hud_text(), yellow))
        if self.config_error:
            lines.append(("config error, keeping the last good config:", red))
            lines.append((self.config_error, red))
        if self.recorded is not None:
            lines.append((f"REC camera path: {len(self.recorded)} pose(s), P stops and saves", red))
        if self.message and time.perf_counter() < self._message_until:
            lines.append((self.message, yellow))
        lines.append(("H: help", dim))
        width = text_width_for(fb)
        return [(piece, color) for text, color in lines for piece in _wrap(text, width, self.hud.width)]

    def _draw_hud(self, layout: Layout, fb) -> None:
        from .hud import HELP_COLUMN_GAP, MARGIN, PAD, help_layout

        hud = self.hud
        hud.set_window_size(fb)  # the font follows the window
        if self.state.hud and not self.state.help:
            hud.panel(MARGIN, MARGIN, hud_fitted(self.hud_lines(layout, fb), fb[1], hud.line_height), pad=PAD)
        if self.state.help:
            place = help_layout(fb, KEYS, hud.font_size, hud.measure)
            hud.use_font_size(place.font_size)
            x, y, w, h = place.box
            hud.rect(x, y, w, h, (0.0, 0.0, 0.0, 0.8))
            rows = [("rayvr preview: keys", None)] + list(KEYS)
            for i, (k, d) in enumerate(rows):
                column, row = divmod(i, place.rows)
                tx = x + PAD + column * (place.column_width + HELP_COLUMN_GAP)
                ty = y + PAD + row * hud.line_height
                if d is None:
                    hud.text(tx, ty, k, (1, 0.85, 0.3, 1))
                    continue
                hud.text(tx, ty, k, (0.6, 0.85, 1.0, 1.0))
                hud.text(tx + place.key_width, ty, d)
        hud.draw(fb)

    # -- loop and lifetime --------------------------------------------------------------
    def should_close(self) -> bool:
        return self.state.quit or bool(self.glfw.window_should_close(self.window))

    def run(self, max_frames: int | None = None) -> None:
        while not self.should_close() and (max_frames is None or self.frames < max_frames):
            self.glfw.poll_events()
            self.frame()

    def close(self) -> None:
        if self.window is None:
            return
        if self.recorded is not None:
            self.save_recording()
        for obj in (self.eye_vao, self.eye_program, self.sampler, self.pick_program, self.pick_buffer):
            obj.release()
        self.hud.release()
        self.renderer.release()
        self.gl.release()  # destroys the window
        self.window = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
