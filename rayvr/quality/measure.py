"""One render variant measured: a material config, render settings, a resolution scale and samples
per image, rendered on a stereo rig; its cost is the median GPU time of the whole frame (the sum
of the passes' timer queries), its image what the viewer would see. Choosing effects under a frame
budget (`--budget-ms`, rayvr/quality/budget.py) runs on this, and so do the benchmarks' sweeps
(rayvr/bench/tradeoff.py); both judge a variant against the reference (rayvr/quality/reference_images.py)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..frame.cameras import DEFAULT_CAMERA_MODEL
from ..frame.cameras.rig import StereoRig
from ..scene.materials import MaterialConfig
from .reference_images import QUICK_QUALITY, reference_settings
from .rungs import parse_rung
from ..frame.passes.quadtree import screen_space_refusal
from ..renderer import Renderer, RenderSettings


def _compare_settings():
    """One RenderSettings for the reference and every variant, so only the knob differs: no
    ambient term (it stands in for indirect light, which only the reference would model), the
    ACES tonemapper users see."""
    return reference_settings(tonemapper="aces")


# The reference draws other random numbers than the variants it judges: with a shared seed a
# variant at a sample count shares the reference's noise and scores better than it should.
REFERENCE_SEED = 0x5EED0001
NOISE_FLOOR_SEED = REFERENCE_SEED + 1  # the reference again with other samples: the error floor of every plot
WARMUP_FRAMES = 3  # frames measure() renders before it times any
SOFTWARE_WARMUP_FRAMES = 1  # the same on a software rasterizer (llvmpipe), which has no clocks to ramp
# An image that costs more than this (a glossy(16) or 4-spp path sweep point: 150-620 ms on Sponza
# on the GPU, 5 s of a budget run each) is timed over SLOW_IMAGE_REPEAT images with no warm-up
# after the settle: a bench budget grid spends its time on the rungs no budget can afford.
SLOW_IMAGE_MS = 50.0
SLOW_IMAGE_REPEAT = 2
# measure()'s clock settle gives up after this (the renderer's default is 10 s): in a sweep the GPU
# has just rendered the previous variant, so its clocks are up, and frames whose times jitter by
# more than the settle's 3 % would otherwise hold every variant for the whole 10 s.
MEASURE_SETTLE_MAX_S = 2.0


def reference_variant(config: MaterialConfig) -> "Variant":
    """The reference as a variant: COMPARE_SETTINGS but its own seed."""
    return Variant("reference", "reference", config, replace(COMPARE_SETTINGS, seed=REFERENCE_SEED))


# The reference for GPU sweeps at 2x1440x1600: REFERENCE_QUALITY's 256 glossy samples x 256
# area samples per hit would take minutes a frame there; this converges to within the FLIP
# differences the knobs make (64 glossy directions or paths, 16 light samples, 4 bounces).
BENCH_QUALITY = {"bounces": 4, "samples": 64, "area_samples": 16, "path_samples": 64}
# BENCH_QUALITY's samples are one frame's; the reference accumulates still frames to this many samples a pixel (bench tradeoff
# and budget, --reference-spp). At 64 in one frame the room's reference differed from itself with
# another seed by FLIP 0.23 (caustic paths NEE cannot sample): more than any knob's difference.
REFERENCE_SPP = 2048
QUICK_REFERENCE_SPP = 128


def reference_per_frame(quick: bool) -> int:
    """Samples a pixel one frame of the bench reference draws (its paths and glossy directions)."""
    return (QUICK_QUALITY if quick else BENCH_QUALITY)["path_samples"]


@dataclass
class Variant:
    knob: str  # what is varied ("effect", "bounces", "resolution_scale", ...)
    value: object
    config: MaterialConfig
    settings: RenderSettings = field(default_factory=lambda: COMPARE_SETTINGS)
    scale: float = 1.0  # render at scale x size, compare upscaled to full size
    touches: tuple = ()  # material names this variant changes (the error mask); () = whole image
    spp: int = 1  # samples accumulated per image (its cost: spp x the GPU ms of one sample)
    camera: str | None = None  # the rig's camera model instead of its own (a registered name)

    @property
    def label(self) -> str:
        return f"{self.knob}={self.value}"


COMPARE_SETTINGS = _compare_settings()


@dataclass
class Measured:
    gpu_ms: float
    image: np.ndarray  # uint8 HxWx3, both eyes side by side, full size
    material: np.ndarray | None  # uint32 HxW material index per pixel (same layout); None: --stereo warp
    hdr: np.ndarray | None = None  # HxWx4 linear radiance (same layout) when measure() was asked for it
    seconds: dict = field(default_factory=dict)  # wall time of its phases: renderer (set up), settle, render
    passes: dict = field(default_factory=dict)  # pass name -> median GPU ms (x spp, as gpu_ms), the budget's cost model


def config_for_assignment(base: MaterialConfig, scene, effects: dict) -> MaterialConfig:
    """A config giving each material (by index, so glob characters in names cannot misfire) the
    rung in `effects` (default `raster`): its effect, with the base config's parameters for it when
    the effect is the one the base gives it, and the rung's own setting on top (quality/rungs.py)."""
    names = scene.material_names()
    by_id = {}
    for i, (name, a) in enumerate(zip(names, base.assign(names, warn=False))):
        e, setting = parse_rung(effects.get(name, "raster"))
        by_id[i] = (e, {**(a.params if a.effect == e else base.effect_params(e)), **setting})
    return MaterialConfig(default="raster", params={k: dict(v) for k, v in base.params.items()}, by_id=by_id,
                          source=f"{base.source} (assignment)")


class RendererPool:
    """One Renderer per (scene, settings), reused across variants: a variant only swaps the
    material config, so shaders compile and the BVH builds once per sweep, not per variant."""

    def __init__(self, gl):
        self.gl, self._renderers = gl, {}

    def get(self, scene, settings: RenderSettings, config: MaterialConfig) -> Renderer:
        key = (id(scene), repr(settings))
        r = self._renderers.get(key)
        if r is None:
            r = self._renderers[key] = Renderer(scene, config, gl=self.gl, settings=settings)
        else:
            r.set_materials(config)
        return r

    def release(self) -> None:
        for r in self._renderers.values():
            r.release()
        self._renderers.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def measure(gl, scene, rig: StereoRig, variant: Variant, repeat: int = 10, warmup: int = WARMUP_FRAMES,
            pool: RendererPool | None = None, hdr: bool = False, settle: bool = True) -> Measured:
    """`variant` rendered `warmup` + `repeat` times on `rig` (after the GPU's clocks settle unless
    `settle` is False); its median GPU ms, the last image (its linear radiance too with `hdr`)."""
    w, h = rig.size
    small = (max(1, round(w * variant.scale)), max(1, round(h * variant.scale)))
    own = pool is None
    pool = pool or RendererPool(gl)
    clock = [time.perf_counter()]
    seconds = {}

    def lap(name):
        clock.append(time.perf_counter())
        seconds[name] = clock[-1] - clock[-2]

    r = pool.get(scene, variant.settings, variant.config)
    lap("renderer")
    try:
        sized = rig.with_size(small)
        if variant.camera is not None:
            sized = replace(sized, camera=variant.camera)
        software = r.gl.is_software  # no clocks to bring up: no settle, one frame for first-use work
        settled = r.warm_up(sized, max_seconds=MEASURE_SETTLE_MAX_S) if settle and not software else {}
        lap("settle")
        if variant.settings.temporal:
            # its image holds every frame from here on (warmup + repeat, the knob's value): none of
            # the settle's frames, nor of an earlier variant's on the pool's renderer
            r.accumulator.invalidate()
        elif software:
            warmup = min(warmup, SOFTWARE_WARMUP_FRAMES)
        elif settled.get("last", 0.0) * variant.spp > SLOW_IMAGE_MS:
            # the settle ran frames of it at speed already, and a timer's jitter is nothing beside this many ms
            warmup, repeat = 0, min(repeat, SLOW_IMAGE_REPEAT)
        rigs = [sized] * (warmup + repeat)
        totals, per_pass, last = [], [], None
        # warp synthesizes the right eye's colour alone: its material map is the reference's to give
        aux = () if variant.settings.stereo == "warp" else ("material",)
        if hdr:
            if small != (w, h):
                raise ValueError("measure(hdr=True) needs the variant at full size (scale 1)")
            aux += ("hdr",)
        for i, frame in enumerate(r.render_sequence(rigs, aux=aux, spp=variant.spp)):
            if i >= warmup:  # an image of spp samples costs spp frames (their last one timed)
                totals.append(sum(frame.timings.values()) * variant.spp)
                per_pass.append(frame.timings)
            last = frame
        lap("render")
    finally:
        if own:
            pool.release()
    image = np.hstack([last.left.color, last.right.color])
    material = np.hstack([last.left.aux["material"], last.right.aux["material"]]) if "material" in aux else None
    radiance = np.hstack([last.left.aux["hdr"], last.right.aux["hdr"]]) if hdr else None
    if small != (w, h):
        from PIL import Image

        image = np.asarray(Image.fromarray(image).resize((2 * w, h), Image.BILINEAR))
        if material is not None:
            material = np.asarray(Image.fromarray(material.astype(np.int32)).resize((2 * w, h), Image.NEAREST)
                                  ).astype(np.uint32)
    passes = {p: float(np.median([t.get(p, 0.0) for t in per_pass])) * variant.spp for p in per_pass[-1]}
    return Measured(float(np.median(totals)), image, material, radiance, seconds, passes)


def camera_refusal(variant: Variant, names, rig: StereoRig | None = None) -> str | None:
    """Why `variant`'s camera (its own, else the rig's, else the pinhole) cannot render its config's
    effects on the materials `names`, or None (screen-space tracing needs the pinhole's depth:
    renderer.plan refuses it)."""
    camera = variant.camera or (getattr(rig.camera, "name", rig.camera) if rig is not None else DEFAULT_CAMERA_MODEL)
    return screen_space_refusal({a.effect for a in variant.config.assign(names, warn=False)}, camera)


@dataclass
class Reference:
    """The converged image every variant is judged against, and its own noise."""
    measured: Measured  # image: the two halves' mean radiance through the display transform
    halves: tuple[Measured, Measured]  # each half the samples, with its own seed
    samples: int  # samples per pixel of `measured` (both halves); its gpu_ms: both halves' cost


def measure_reference(gl, scene, rig: StereoRig, reference: Variant, samples: int, samples_per_frame: int,
                      pool: RendererPool | None = None) -> Reference:
    """`reference` accumulated to about `samples` per pixel, as two halves of still frames: one with
    its seed, one with NOISE_FLOOR_SEED. Its image is the halves' mean radiance, tonemapped here
    as the GPU would (quality/tonemap.py); the halves' FLIP against each other is the noise floor,
    a conservative one: each half has half the reference's samples.
    `samples_per_frame`: what one frame of `reference` draws (its config's sample counts)."""
    from .tonemap import to_ldr

    frames = max(1, round(samples / (2 * samples_per_frame)))
    one = replace(reference, spp=frames)
    other = replace(one, settings=replace(one.settings, seed=NOISE_FLOOR_SEED))
    # no settling: the reference's time is reported, never judged, and a warm-up of its frames costs seconds
    a, b = (measure(gl, scene, rig, v, repeat=1, warmup=0, pool=pool, hdr=True, settle=False) for v in (one, other))
    s = reference.settings
    mean = (a.hdr.astype(np.float32) + b.hdr.astype(np.float32)) * 0.5
    return Reference(Measured(a.gpu_ms + b.gpu_ms, to_ldr(mean, s.tonemapper, s.exposure), a.material, mean),
                     (a, b), 2 * frames * samples_per_frame)


def local_measurer(gl, scene, rig: StereoRig, repeat: int, pool: RendererPool | None = None):
    """`measure_all(variants, bar)`: each variant measured here, in order, the bar counting them.
    rayvr.app.cluster.sweep_measurer is the same over Ray workers (`rayvr bench tradeoff --workers`)."""
    def measure_all(variants, bar=None):
        for v in variants:
            m = measure(gl, scene, rig, v, repeat, pool=pool)
            if bar is not None:
                bar.update(1)
            yield m
    return measure_all
