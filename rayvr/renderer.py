"""`Renderer(scene, materials).render(rig)`: the Python entry point, familiar to pyrender users.

    from rayvr import Renderer, StereoRig, Pose
    r = Renderer()                                   # built-in default scene, all-`raster`
    rig = StereoRig.for_scene(r.scene, size=(640, 480))
    frame = r.render(rig)
    frame.left.color   # (H, W, 3) uint8 sRGB, rows top-down
    frame.left.depth   # (H, W) float32 linear view depth (0 = background, like pyrender)
    frame.timings      # {pass name: GPU ms} from GL timer queries
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import materials as materials_mod
from . import scene as scene_mod
from .camera import EyeView, StereoRig
from .context import GLContext, create_context
from .frame import FramePlan, PassTimer, schedule
from .gbuffer import GBuffer
from .gpu_scene import GpuScene
from .passes.debug_view import DEBUG_VIEWS, DebugViewPass
from .passes.gbuffer import GBufferResolvePass, VisibilityPass, pick_layer_mode
from .passes.resolve import TONEMAPPERS, ResolvePass
from .passes.raytrace import all_rt_passes
from .passes.shade import ShadeDirectPass
from .accel.scene import SceneAccel
from .readback import AUX_CHANNELS, Reader

VIEWS = ("color",) + DEBUG_VIEWS
PRIMARY_MODES = ("raster", "rays")


@dataclass
class RenderSettings:
    exposure: float = 1.0
    tonemapper: str = "aces"  # aces | reinhard | clamp (glsl/common/color.glsl)
    ambient: tuple = (0.03, 0.03, 0.03)
    background: tuple = (0.02, 0.02, 0.025)
    layer_mode: str = "auto"  # auto | vertex | geometry | multiview | passes
    primary: str = "raster"  # primary visibility: raster (visibility pass) | rays (BVH, passes/raytrace.py)
    seed: int = 0  # random sequence of the sampled effects (area-light points, glossy rays)

    def __post_init__(self):
        if self.tonemapper not in TONEMAPPERS:
            raise ValueError(f"unknown tonemapper {self.tonemapper!r}; allowed: {', '.join(TONEMAPPERS)}")
        if not (np.isfinite(self.exposure) and self.exposure > 0):
            raise ValueError(f"exposure must be a positive number, got {self.exposure}")
        if self.primary not in PRIMARY_MODES:
            raise ValueError(f"unknown primary visibility {self.primary!r}; allowed: {', '.join(PRIMARY_MODES)}")


@dataclass
class EyeImage:
    name: str
    color: np.ndarray
    depth: np.ndarray
    aux: dict = field(default_factory=dict)

    def __iter__(self):  # color, depth = frame.left
        return iter((self.color, self.depth))


@dataclass
class Frame:
    eyes: dict
    timings: dict
    view: str

    @property
    def left(self) -> EyeImage:
        return self.eyes["left"]

    @property
    def right(self) -> EyeImage:
        return self.eyes["right"]

    def __getitem__(self, eye: str) -> EyeImage:
        return self.eyes[eye]


@dataclass
class FrameContext:
    """What passes see while a frame is recorded."""

    gl: GLContext
    scene: scene_mod.Scene
    gpu_scene: GpuScene
    gbuffer: GBuffer
    eyes: list[EyeView]
    plan: FramePlan
    settings: RenderSettings
    targets: dict
    accel: SceneAccel | None = None  # the scene's BVH, built by the `bvh` pass when one is needed

    def target(self, name: str):
        return self.targets[name]


def _as_config(materials) -> materials_mod.MaterialConfig:
    """A MaterialConfig as given, or loaded and validated from a path (None: all `raster`)."""
    if isinstance(materials, materials_mod.MaterialConfig):
        return materials
    return materials_mod.load_config(materials)


def _all_passes():
    """Every pass rayvr has, in registration order (the graph picks and orders what runs)."""
    rt = all_rt_passes()
    return [rt["bvh"], VisibilityPass(), rt["primary_rays"], GBufferResolvePass(), ShadeDirectPass(), rt["classify"],
            rt["rt_shadows"], rt["rt_reflections"], rt["rt_glossy"], ResolvePass(), DebugViewPass()]


class Renderer:
    def __init__(self, scene=None, materials=None, *, gl: GLContext | None = None, backend: str | None = None,
                 settings: RenderSettings | None = None):
        self.scene = scene if isinstance(scene, scene_mod.Scene) else scene_mod.load(scene)
        self._owns_gl = gl is None
        self.gl = gl or create_context(backend)
        self.settings = settings or RenderSettings()
        self.config = _as_config(materials)
        self.assignments = self.config.assign(self.scene.material_names())
        self.gpu_scene = GpuScene(self.gl, self.scene, self.assignments)
        self.layer_mode = pick_layer_mode(self.gl, self.settings.layer_mode)
        self.timer = PassTimer(self.gl.ctx)
        self.accel = SceneAccel(self.gl, self.scene)  # BVH: built only when a pass needs it
        self.reader = Reader(self.gl)
        self._passes: dict = {}  # plan key -> scheduled, set-up passes
        self._gbuffer: GBuffer | None = None
        self._targets: dict = {}

    # -- configuration ---------------------------------------------------------------
    def set_materials(self, materials) -> None:
        """Swap the material config (a path or MaterialConfig); validation errors leave the
        current one in place."""
        config = _as_config(materials)
        assignments = config.assign(self.scene.material_names())
        self.config, self.assignments = config, assignments
        self.gpu_scene.set_assignments(assignments)

    def effects_in_use(self) -> frozenset:
        return frozenset(a.effect for a in self.assignments)

    # -- rendering -------------------------------------------------------------------
    def _plan(self, layers: int, view: str) -> FramePlan:
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; allowed: {', '.join(VIEWS)}")
        return FramePlan(effects=self.effects_in_use(), view=view, layers=layers, layer_mode=self.layer_mode,
                         primary=self.settings.primary)

    def passes_for(self, plan: FramePlan) -> list:
        key = (plan.effects, plan.view, plan.layers, plan.layer_mode, plan.primary)
        if key not in self._passes:
            chosen = schedule(_all_passes(), plan)
            for p in chosen:
                p.setup(self.gl, plan)
            self._passes[key] = chosen
        return self._passes[key]

    def _resources(self, size, layers):
        if self._gbuffer is None or self._gbuffer.size != tuple(size) or self._gbuffer.layers != layers:
            self._release_resources()
            ctx = self.gl.ctx
            self._gbuffer = GBuffer(self.gl, size, layers)
            self._targets = {
                "hdr": ctx.texture_array((*size, layers), 4, dtype="f2"),
                "ldr": ctx.texture_array((*size, layers), 4, dtype="f1"),
            }
        return self._gbuffer, self._targets

    def record(self, rig: StereoRig, eyes: str = "both", view: str = "color") -> FrameContext:
        """Run the frame's passes on the GPU (no readback); returns the context for readback."""
        eye_views = rig.eyes(eyes)
        plan = self._plan(len(eye_views), view)
        passes = self.passes_for(plan)
        gbuffer, targets = self._resources(rig.size, len(eye_views))
        fc = FrameContext(self.gl, self.scene, self.gpu_scene, gbuffer, eye_views, plan, self.settings, targets,
                          self.accel)
        self.timer.next_frame()
        for p in passes:
            self.timer.run(p.name, lambda p=p: p.execute(fc))
        fc.pass_names = [p.name for p in passes]
        return fc

    def warm_up(self, rig: StereoRig, eyes: str = "both", view: str = "color", seconds: float | None = None,
                min_frames: int = 1) -> None:
        """Render for `seconds` without reading anything back: an idle GPU runs at a fraction of
        its clock (the H200 idles at 345 MHz against 1980 MHz) and needs ~0.2 s of work to ramp
        up, so timings taken straight after a pause measure the clock governor, not rayvr.
        Default: 0.3 s on a GPU, one frame on a software rasterizer (no clocks to ramp)."""
        import time

        if seconds is None:
            seconds = 0.0 if self.gl.is_software else 0.3
        end, done = time.perf_counter() + seconds, 0
        while done < min_frames or time.perf_counter() < end:
            self.record(rig, eyes, view)
            self.gl.ctx.finish()
            done += 1

    def render(self, rig: StereoRig, eyes: str = "both", view: str = "color", aux=()) -> Frame:
        """Render one frame; `eyes` is 'both', 'left' or 'right'; `aux` names extra G-buffer
        channels to read back (AUX_CHANNELS)."""
        return next(self.render_sequence([rig], eyes, view, aux))

    def render_sequence(self, rigs, eyes: str = "both", view: str = "color", aux=()):
        """Yield one Frame per rig. Frame N is read back while frame N+1 renders (pixel
        buffers and timer queries are double-buffered), so sequences run at GPU speed."""
        unknown = [a for a in aux if a not in AUX_CHANNELS]
        if unknown:
            raise ValueError(f"unknown aux channel(s) {', '.join(unknown)}; allowed: {', '.join(AUX_CHANNELS)}")
        pending = None
        for i, rig in enumerate(rigs):
            fc = self.record(rig, eyes, view)
            started = self.reader.start(fc, tuple(aux), parity=i % 2, timer_slot=self.timer.slot)
            if pending is not None:
                yield self._finish(pending)
            pending = started
        if pending is not None:
            yield self._finish(pending)

    def _finish(self, pending) -> Frame:
        timings = self.timer.read_ms(pending.fc.pass_names, slot=pending.timer_slot)
        return Frame(self.reader.finish(pending), timings, pending.fc.plan.view)

    def update_vertices(self, vertices) -> None:
        """Move the scene's vertices (scene-local, same triangles): re-upload them and refit the
        BVH if one was built."""
        v = np.asarray(vertices, np.float32)
        if v.shape != self.scene.vertices.shape or not np.isfinite(v).all():
            raise ValueError(f"update_vertices needs {self.scene.vertices.shape} finite positions, got {v.shape}")
        self.scene.vertices = np.ascontiguousarray(v)
        self.gpu_scene.upload_vertices()
        self.accel.refit(v)

    # -- lifetime --------------------------------------------------------------------
    def _release_resources(self) -> None:
        if self._gbuffer is not None:
            self._gbuffer.release()
            for t in self._targets.values():
                t.release()
        self._gbuffer, self._targets = None, {}

    def release(self) -> None:
        self._release_resources()
        self.reader.release()
        for passes in self._passes.values():
            for p in passes:
                p.release()
        self._passes.clear()
        self.accel.release()
        self.gpu_scene.release()
        if self._owns_gl:
            self.gl.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
