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

import dataclasses
import os
import warnings
from dataclasses import replace

import numpy as np

from .frame import effects as effects_mod
from .scene import materials as materials_mod
from .scene import loader as scene_mod
from .frame import stereo as stereo_mod
from .accel.scene import SceneAccel
from .frame.accumulation import Accumulator, sample_seed
from .frame.cameras.rig import StereoRig
from .frame.cameras import CAMERA_MODELS, DEFAULT_CAMERA_MODEL, get_camera_model
from .gl.context import GLContext, GpuError, create_context
from .frame.graph import (EyeImage, Frame, FrameContext, FrameGraph, FramePlan, FrameTooLarge, Sizing, check_fits,
                    limit_problems)
from .gl.gpu_layout import VIEWS
from .scene.gpu_scene import GpuScene
from .frame.passes import primary_rays
from .frame.passes.core import core_passes
from .frame.cameras import sampling
from .frame.passes import accumulate as accumulate_pass, denoise, dof, persistent_threads, quadtree, second_layer
from .options import PlanAsk, plan_fields
from .frame.passes.classify import pixel_counts
from .frame.passes.second_layer import depth_layers
from .frame.passes.visibility import pick_layer_mode
from .frame.readback import AUX_CHANNELS, Reader
from .settings import RenderSettings
from .gl.timing import settle

# The modules whose plan parts make a FramePlan (rayvr/options.py plan_part: each registers its own
# on import); Renderer.plan runs them all.
PLAN_OWNERS = (sampling, primary_rays, second_layer, denoise, stereo_mod, dof, quadtree, accumulate_pass,
               persistent_threads)
MAX_TILES = 64  # a frame that needs more tiles than this is refused (FrameTooLarge) instead
HOST_BYTES_PER_PIXEL = 16  # colour, depth and the pixel buffers they come through, per eye pixel
SAMPLES_IN_FLIGHT = 2  # samples of an accumulation queued on the GPU before the next is recorded


def work_dropped(timings: dict) -> bool:
    """Whether a hardware GPU's pass timings say the frame's commands never ran: most passes at
    exactly 0 ns (a pass that records nothing still reads about 1 us there). Seen on the NVIDIA GPU
    when a fresh Renderer had queued ~20 s of samples: stale pixels, no GL error."""
    zeros = sum(v == 0.0 for v in timings.values())
    return len(timings) >= 2 and zeros * 2 > len(timings)


def _as_config(materials) -> materials_mod.MaterialConfig:
    """A MaterialConfig as given, or loaded and validated from a path (None: all `raster`)."""
    if isinstance(materials, materials_mod.MaterialConfig):
        return materials
    return materials_mod.load_config(materials)


def candidate_passes(plan: FramePlan) -> list:
    """The passes a plan may use: the core ones and those of the effects it uses (an effect's pass
    named like a core one, e.g. `quadtree`, is that one: the core pass is kept)."""
    out = core_passes()
    for e in effects_mod.EFFECTS.values():
        if e.name in plan.effects:
            out += [p for p in e.passes() if p.name not in {q.name for q in out}]
    return out


class Renderer:
    def __init__(self, scene=None, materials=None, *, gl: GLContext | None = None, backend: str | None = None,
                 settings: RenderSettings | None = None, skip_empty_slots: bool = True,
                 wave_buffer_bytes: int | None = None):
        """`skip_empty_slots` (FramePlan) and `wave_buffer_bytes` (Sizing: the largest wavefront
        buffer, default frame/passes/trace_effect.py WAVE_BUFFER_BYTES) are for tests that compare the
        fast paths with their references; the frames are the same either way."""
        if wave_buffer_bytes is not None and not (isinstance(wave_buffer_bytes, int) and wave_buffer_bytes > 0):
            raise ValueError(f"wave_buffer_bytes must be a positive whole number of bytes, got {wave_buffer_bytes!r}")
        self.scene = scene if isinstance(scene, scene_mod.Scene) else scene_mod.load(scene)
        self._owns_gl = gl is None
        self.gl = gl or create_context(backend)
        self.gl.make_current()  # every call of a Renderer into GL starts so (GLContext.make_current)
        self.settings = settings or RenderSettings()
        self.skip_empty_slots = bool(skip_empty_slots)
        self.wave_buffer_bytes = wave_buffer_bytes
        self.config = _as_config(materials)
        self.assignments = self.config.assign(self.scene.material_names())
        self.gpu_scene = GpuScene(self.gl, self.scene, self.assignments)
        self.layer_mode = pick_layer_mode(self.gl, self.settings.layer_mode)
        self.accel = SceneAccel(self.gl, self.scene)  # BVH: built only when a pass needs it
        self.graph = FrameGraph(self.gl, candidate_passes)
        self.reader = Reader(self.gl)
        self._last: FrameContext | None = None
        self._tiles: dict = {}  # the last (plan, size, config, limits) -> tiles answer
        self.accumulator = Accumulator()  # which sample a frame is; reset on any change

    # -- configuration ---------------------------------------------------------------
    def set_materials(self, materials) -> None:
        """Swap the material config (a path or MaterialConfig); validation errors leave the
        current one in place."""
        config = _as_config(materials)
        assignments = config.assign(self.scene.material_names())
        self.gl.make_current()
        self.config, self.assignments = config, assignments
        self.gpu_scene.set_assignments(assignments)
        self.accumulator.invalidate()

    def effects_in_use(self) -> frozenset:
        return frozenset(a.effect for a in self.assignments)

    def denoised_effects(self) -> frozenset:
        """The effects in use whose pixels the denoiser filters: the config's `denoise` list
        (default: the traced effects that declare themselves `denoised`, the sampled ones)."""
        traced = {e.name for e in effects_mod.traced_effects()}
        chosen = {e.name for e in effects_mod.traced_effects() if e.denoised} if self.config.denoise is None \
            else set(self.config.denoise)
        return frozenset(self.effects_in_use() & traced & chosen)

    # -- the frame graph -------------------------------------------------------------
    def plan(self, eyes: int = 2, view: str = "color", camera=None, accumulate: bool = False,
             layers: int | None = None) -> FramePlan:
        """The FramePlan this renderer's scene, config and settings give for `eyes` eyes seen
        through `camera` (a rayvr.frame.cameras model; default the pinhole). A camera a rasterizer cannot
        sample (not `rasterizable`), or sub-rays per sample (settings.msaa > 1: anti-aliasing), take
        ray-cast primary visibility whatever the settings say; such a camera refuses (ValueError)
        temporal reprojection and depth of field, which need the eyes' planar frusta.
        `accumulate`: keep a running mean of samples (as `render(spp=N)`) whatever the settings say.
        `layers`: the old name of `eyes`."""
        if layers is not None:
            warnings.warn("Renderer.plan(layers=...) is deprecated: use eyes", DeprecationWarning, stacklevel=2)
            eyes = layers
        camera = camera or get_camera_model(DEFAULT_CAMERA_MODEL)
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; allowed: {', '.join(VIEWS)}")
        names = self.scene.material_names()
        users = tuple((e, tuple(n for n, a in zip(names, self.assignments) if a.effect == e))
                      for e in effects_mod.EFFECTS if e in self.effects_in_use())
        ask = PlanAsk(self.settings, camera, view, eyes, accumulate, self.effects_in_use(),
                      frozenset(self.denoised_effects()), depth_layers(self.assignments))
        frame = dict(effects=self.effects_in_use(), view=view, eyes=eyes, layer_mode=self.layer_mode,
                     camera=camera.name, output="ldr", users=users, channels=camera.channels,
                     reconstruct=camera.sparse, skip_empty_slots=self.skip_empty_slots)
        fields = plan_fields(ask, frame)  # every owner's part (rayvr/options.py plan_part)
        known = {f.name for f in dataclasses.fields(FramePlan)}
        extra = tuple(sorted((k, v) for k, v in fields.items() if k not in known))  # plugins' plan fields
        return FramePlan(**{k: v for k, v in fields.items() if k in known}, extra=extra)

    def set_stereo(self, mode: str) -> None:
        """How the second eye is made from now on: "dual", "warp" or "reuse" (rayvr/frame/stereo.py)."""
        self.settings.stereo = stereo_mod.check_mode(mode)

    def compiled(self, plan: FramePlan | None = None):
        """The compiled frame graph of `plan` (default: both eyes, colour): passes in order,
        resources, reasons; `.describe(sizing)` and `.dot()` print it."""
        return self.graph.compile(plan or self.plan())

    def sizing(self, size, layers: int = 2, plan: FramePlan | None = None) -> Sizing:
        """What `plan`'s resources are sized by (its depth layers: warp may add one)."""
        return Sizing(tuple(size), layers, self.scene, tuple(self.assignments), self.gl.max_ssbo_bytes,
                      plan.depth_layers if plan is not None else depth_layers(self.assignments), self.wave_buffer_bytes,
                      plan.light_picks if plan is not None else self.settings.light_picks)

    def record(self, rig: StereoRig, eyes: str = "both", view: str = "color", profile: bool = False,
               sample: int | None = None) -> FrameContext:
        """Run the frame's passes on the GPU (no readback); returns the context for readback.
        `profile`: time each kernel of multi-kernel passes instead of each pass (read_ms).
        `sample`: this frame is that sample of an accumulation (0 starts over); None: the
        accumulator decides (rayvr/frame/accumulation.py: the next sample while nothing changed)."""
        self.gl.make_current()
        eye_views = rig.eyes(eyes)
        plan = self.plan(len(eye_views), view, eye_views[0].camera, accumulate=sample is not None)
        graph = self.graph.compile(plan)
        rendered = stereo_mod.rendered_eyes(rig, eyes, plan.stereo)  # warp: the central view
        camera = rendered[0].camera.uniforms(rendered, self.scene.origin)
        state = self.accumulator.next(camera, (plan, rig.size, eyes), self.settings, sample)
        settings = replace(self.settings, seed=sample_seed(self.settings.seed, state.sample))
        fc = FrameContext(self.gl, self.scene, self.gpu_scene, self.accel, rendered, plan, settings,
                          self.sizing(rig.size, plan.eyes, plan), samples=state, out_eyes=eye_views)
        self.graph.execute(graph, fc, profile)
        self._last = fc
        return fc

    def read_ms(self, fc: FrameContext) -> dict:
        """GPU ms per pass of a recorded frame (per kernel if it was profiled); waits for the GPU."""
        return self.graph.read_ms(fc)

    def read_round_ms(self, fc: FrameContext) -> dict:
        """GPU ms per pass of a recorded frame, a list with one entry each time the pass ran (once
        per round of a sampled frame); waits for the GPU."""
        return self.graph.read_round_ms(fc)

    def resource(self, name: str):
        """A GL resource of the last recorded frame by its graph name ("hdr", "rt_lists", ...)."""
        if self._last is None or name not in self._last.resources:
            raise KeyError(f"the last frame has no resource {name!r}")
        return self._last.resource(name)

    def stereo_counts(self) -> dict:
        """What the last frame's stereo mode did (reads back): under `reuse` the right-eye pixels
        given the left eye's shading ("reused"); under `warp` each eye's pixels and holes
        ("holes_left", "holes_right", "offscreen_left", ...); {} under `dual`."""
        if self._last is None:
            return {}
        mode = self._last.plan.stereo
        if mode == "reuse" and "reuse_map" in self._last.resources:  # (a debug view shades nothing)
            from .frame.passes.reuse import reuse_counts
            return reuse_counts(self._last)
        if mode == "warp":
            from .frame.passes.warp import warp_counts
            return warp_counts(self._last)
        return {}

    def pixel_counts(self) -> dict:
        """Pixels per traced effect in the last recorded frame (its classify pass); {} if none ran."""
        if self._last is None or "rt_list_args" not in self._last.resources:
            return {}
        return pixel_counts(self._last.resource("rt_list_args"))

    def warm_up(self, rig: StereoRig, eyes: str = "both", view: str = "color", seconds: float | None = None,
                min_frames: int = 1, max_seconds: float = 10.0) -> dict:  # timing.settle's record
        """Render without reading pixels back until the frame's GPU time settles (timing.settle:
        the median of the last 5 frames within 3 % of the 5 before, after at least `seconds`,
        default 0.3 s; giving up after `max_seconds`): timings taken straight after a pause or a build
        measure the clock governor, not rayvr. A software rasterizer has no clocks to ramp: `min_frames` only."""
        def frame_ms() -> float:
            fc = self.record(rig, eyes, view)
            return sum(self.read_ms(fc).values())  # waits for the GPU

        if self.gl.is_software:
            for _ in range(min_frames):
                frame_ms()
            return {"runs": min_frames, "settled": False}
        for _ in range(min_frames):
            frame_ms()
        return settle(frame_ms, min_seconds=0.3 if seconds is None else seconds, max_seconds=max_seconds)

    def render(self, rig: StereoRig, eyes: str = "both", view: str = "color", aux=(), spp: int = 1,
               progress=None) -> Frame:
        """Render one frame; `eyes` is 'both', 'left' or 'right'; `aux` names extra channels to
        read back (AUX_CHANNELS): frame.left.aux[name]. `spp` > 1: the mean of that many samples
        (frames with their own sample index, accumulated from a fresh start); `progress(n)` is
        called as samples are recorded."""
        return next(self.render_sequence([rig], eyes, view, aux, spp, progress))

    def render_sequence(self, rigs, eyes: str = "both", view: str = "color", aux=(), spp: int = 1, progress=None,
                        depth: bool = True):
        """Yield one Frame per rig (each the mean of `spp` samples). Frame N is read back while
        frame N+1 renders (pixel buffers and timer queries are double-buffered), so sequences run
        at GPU speed; a frame's timings are those of its last sample. `depth=False`: the eyes'
        `depth` is None (not read back, unless an aux channel needs it)."""
        if not (isinstance(spp, int) and spp >= 1):
            raise ValueError(f"spp must be a positive integer, got {spp!r}")
        unknown = [a for a in aux if a not in AUX_CHANNELS]
        if unknown:
            raise ValueError(f"unknown aux channel(s) {', '.join(unknown)}; allowed: {', '.join(AUX_CHANNELS)}")
        if "hdr" in aux and view != "color":
            raise ValueError(f"aux channel 'hdr' needs view 'color' (view {view!r} makes no HDR colour)")
        warped = [a for a in aux if a != "depth"] if self.settings.stereo == "warp" and eyes == "both" else []
        if warped:
            raise ValueError(f"aux channel(s) {', '.join(warped)} need stereo dual or reuse: warp makes only "
                             f"colour and depth per eye (its G-buffer is the central view)")
        pending = None
        self.gl.make_current()
        self.gl.gl_errors()  # what earlier calls left (queries of optional limits) is not this frame's
        for i, rig in enumerate(rigs):
            tiles = self.tiles(rig, eyes, view)
            if len(tiles) > 1:  # too large for the device at once: tile by tile, not pipelined
                if pending is not None:
                    yield self._finish(pending)
                    pending = None
                yield self._render_tiles(rig, tiles, eyes, view, aux, spp, progress)  # (with depth)
                continue
            queued: list = []
            for k in range(spp - 1):  # no readback until the last sample
                self.record(rig, eyes, view, sample=k)
                self._limit_queue(queued)
                if progress is not None:
                    progress(1)
            for f in queued:
                f.release()
            fc = self.record(rig, eyes, view, sample=spp - 1 if spp > 1 else None)
            if progress is not None:
                progress(1)
            started = self.reader.start(fc, tuple(aux), parity=i % 2, depth=depth)
            if pending is not None:
                yield self._finish(pending)
            pending = started
        if pending is not None:
            yield self._finish(pending)

    def _limit_queue(self, queued: list) -> None:
        """Keep at most SAMPLES_IN_FLIGHT recorded samples ahead of the GPU. On the NVIDIA GPU a fresh
        Renderer that queued ~20 s of samples without a wait got its readback and timer queries
        back untouched (the previous Renderer's image, 0 ms), with no GL error."""
        queued.append(self.gl.fence())
        if len(queued) > SAMPLES_IN_FLIGHT:
            queued.pop(0).wait()

    def tiles(self, rig: StereoRig, eyes: str = "both", view: str = "color") -> list:
        """The pixel rectangles (x0, y0, x1, y1; rows top-down) a frame is rendered in: the whole
        image when it fits the device, else the fewest equal tiles that do (each an off-axis part
        of the eye's frustum, so the pixels are the same rays). Only a planar camera tiles."""
        eye_views = rig.eyes(eyes)
        plan = self.plan(len(eye_views), view, eye_views[0].camera)
        key = (plan, rig.size, id(self.assignments), self.graph.limits)  # sequences ask once per size
        if key not in self._tiles:
            self._tiles = {key: self._plan_tiles(plan, rig.size, plan.eyes)}
        return self._tiles[key]

    def _plan_tiles(self, plan: FramePlan, size, layers: int) -> list:
        graph = self.graph.compile(plan)
        tileable = CAMERA_MODELS[plan.camera].rasterizable  # a tile is an off-axis part of a planar frustum
        w, h = size
        host = w * h * layers * HOST_BYTES_PER_PIXEL
        ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        if host > ram / 2:
            raise FrameTooLarge(f"a {w}x{h} eye image ({layers} eye(s)) needs about {host / 2**30:.1f} GiB "
                                f"of host memory for its pixels, of {ram / 2**30:.1f} GiB")
        if not limit_problems(graph, self.sizing((w, h), layers, plan), self.graph.limits):
            return [(0, 0, w, h)]
        if not tileable:
            check_fits(graph, self.sizing((w, h), layers, plan), self.graph.limits)  # raises, saying why
        nx = ny = 1
        while limit_problems(graph, self.sizing((-(-w // nx), -(-h // ny)), layers, plan), self.graph.limits):
            if nx * ny >= MAX_TILES:
                check_fits(graph, self.sizing((w, h), layers, plan), self.graph.limits)
            nx, ny = (nx * 2, ny) if -(-w // nx) >= -(-h // ny) else (nx, ny * 2)
        xs = [w * i // nx for i in range(nx + 1)]
        ys = [h * j // ny for j in range(ny + 1)]
        return [(xs[i], ys[j], xs[i + 1], ys[j + 1]) for j in range(ny) for i in range(nx)]

    def _render_tiles(self, rig: StereoRig, tiles: list, eyes: str, view: str, aux, spp: int = 1,
                      progress=None) -> Frame:
        w, h = rig.size
        full = {e.name: e for e in rig.eyes(eyes) + ([rig.eye("center")] if eyes == "both" else [])}
        out: dict = {}
        timings: dict = {}
        passes: tuple = ()
        for x0, y0, x1, y1 in tiles:
            sub = {}
            for name, e in full.items():
                l, r, b, t = e.tangents
                sub[name] = (l + (r - l) * x0 / w, l + (r - l) * x1 / w,
                             t - (t - b) * y1 / h, t - (t - b) * y0 / h)  # rows go top-down, tangents up
            part = self.render(replace(rig, size=(x1 - x0, y1 - y0), eye_tangents=sub), eyes, view, aux, spp, progress)
            for k, v in part.timings.items():
                timings[k] = timings.get(k, 0.0) + v
            passes = part.passes
            for name, img in part.eyes.items():
                whole = out.setdefault(name, EyeImage(name, np.zeros((h, w, 3), np.uint8), np.zeros((h, w), np.float32),
                                                      {k: np.zeros((h, w) + a.shape[2:], a.dtype)
                                                       for k, a in img.aux.items()}))
                whole.color[y0:y1, x0:x1] = img.color
                whole.depth[y0:y1, x0:x1] = img.depth
                for k, a in img.aux.items():
                    whole.aux[k][y0:y1, x0:x1] = a
        return Frame(out, timings, view, passes)

    def _finish(self, pending) -> Frame:
        self.gl.make_current()
        timings = self.graph.read_ms(pending.fc)
        frame = Frame(self.reader.finish(pending), timings, pending.fc.plan.view, tuple(pending.fc.pass_names))
        where = f"a {'x'.join(map(str, pending.fc.sizing.size))} frame"
        self.gl.check_frame(where)
        if not self.gl.is_software and work_dropped(timings):
            raise GpuError(f"{where}: the GPU timed {sum(v == 0.0 for v in timings.values())} of its "
                           f"{len(timings)} passes at 0 ns, so their commands did not run; the image "
                           f"would be an earlier one ({self.gl.ctx.info.get('GL_RENDERER', 'unknown renderer')})")
        return frame

    def update_vertices(self, vertices, gpu_refit: bool = False) -> None:
        """Move the scene's vertices (scene-local, same triangles): re-upload them and refit the
        BVH if one was built (on the host, or with `gpu_refit` in a compute pass: accel/refit.py)."""
        v = np.asarray(vertices, np.float32)
        if v.shape != self.scene.vertices.shape or not np.isfinite(v).all():
            raise ValueError(f"update_vertices needs {self.scene.vertices.shape} finite positions, got {v.shape}")
        self.scene.vertices = np.ascontiguousarray(v)
        self.accumulator.invalidate()
        self.gl.make_current()
        self.gpu_scene.upload_vertices()
        self.accel.refit(v, on_gpu=gpu_refit)

    # -- lifetime --------------------------------------------------------------------
    def release(self) -> None:
        self.gl.make_current()
        self.reader.release()
        self.graph.release()
        self.accel.release()
        self.gpu_scene.release()
        if self._owns_gl:
            self.gl.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
