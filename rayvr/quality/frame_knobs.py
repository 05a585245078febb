"""The frame-wide knobs a budget pick chooses beside the per-material effects: the stereo mode,
samples per pixel, the denoiser and its iterations, the MSAA count, the resolution scale,
temporal accumulation and the camera model (those judged by the pinhole). One `FrameKnobs` is one
value of each; a grid (`--frame-knobs "stereo=dual,reuse;spp=1,4;denoise=off,on"`) is every
combination of the values given, each knob left out at its default.

A knob changes what every material's effect costs and how much error it leaves (`reuse` shades
the right eye from the left's, a lower scale raises every error, the denoiser's cost follows the
pixels it filters), so nothing is assumed about how knobs and effects combine: the budget
measures each material's table under each point of the grid (quality/frame_budget.py).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, fields, replace

from ..frame.stereo import STEREO
from ..frame.cameras import CAMERA_MODELS, DEFAULT_CAMERA_MODEL as DEFAULT_CAMERA
from ..frame.cameras.sampling import MSAA
from ..frame.passes.denoise import DENOISE_ITERATIONS
from ..options import BOOL_WORDS
from ..settings import merged

MAX_SPP = 64  # a budget pick accumulates at most this many samples an image
SCALES = (0.5, 1.0)  # a resolution scale lies in [0.5, 1]: below half the upscaled image is a blur


def cameras() -> tuple:
    """The camera models a pick may take: those that declare their image the pinhole's
    (CameraModel.judged_by_pinhole), so the pinhole reference judges them; a plugin's too, once
    registered (a distorted or wide image is another)."""
    return tuple(name for name, model in CAMERA_MODELS.items() if model.judged_by_pinhole)


@dataclass(frozen=True)
class FrameKnobs:
    stereo: str = "dual"
    spp: int = 1
    denoise: bool = False
    msaa: int = 1
    scale: float = 1.0
    temporal: bool = False  # on a still view its image holds every frame measured: an optimist's figure
    camera: str = DEFAULT_CAMERA
    iterations: int = DENOISE_ITERATIONS.default  # the denoiser's a-trous iterations (with denoise on)

    @property
    def label(self) -> str:
        return " ".join(f"{f.name}={_text(getattr(self, f.name))}" for f in fields(self)
                        if f.name != "iterations" or self.denoise)  # iterations mean nothing without it

    def render_table(self) -> dict:
        """The knobs that are render options, as a config's [render] table holds them."""
        out = {"stereo": self.stereo, "denoise": self.denoise, "msaa": self.msaa}
        if self.denoise and self.iterations != DENOISE_ITERATIONS.default:
            out["denoise_iterations"] = self.iterations
        return {**out, "temporal": True} if self.temporal else out

    def settings(self, base):
        """`base` RenderSettings with these knobs' render options and what they imply (temporal: accumulation)."""
        return replace(base, **merged(self.render_table()))

    def variant(self, knob: str, value, config, base_settings):
        """A measured variant (quality/measure.py) rendered with these knobs."""
        from .measure import Variant

        return Variant(knob, value, config, self.settings(base_settings), scale=self.scale, spp=self.spp,
                       camera=None if self.camera == DEFAULT_CAMERA else self.camera)

    def capture_flags(self, size: tuple[int, int] | None = None) -> str:
        """The capture flags the config's [render] table cannot hold: samples per pixel, the camera
        model, and the scaled per-eye size (the frame was measured rendered at it and shown upscaled)."""
        out = [f"--spp {self.spp}"] if self.spp > 1 else []
        if self.camera != DEFAULT_CAMERA:
            out.append(f"--camera-model {self.camera}")
        if self.scale != 1.0 and size is not None:
            out.append(f"--size {max(1, round(size[0] * self.scale))}x{max(1, round(size[1] * self.scale))}")
        return " ".join(out)


DEFAULT_KNOBS = FrameKnobs()


def _text(v) -> str:
    return ("on" if v else "off") if isinstance(v, bool) else f"{v:g}" if isinstance(v, float) else str(v)


def _one(name: str, text: str):
    """One knob value from its text; ValueError naming the knob and what it takes."""
    t = text.strip().lower()
    if name == "stereo":
        if t not in STEREO.choices:
            raise ValueError(f"frame knob stereo: {text!r} is not one of {', '.join(STEREO.choices)}")
        return t
    if name in ("denoise", "temporal"):
        if t not in BOOL_WORDS:
            raise ValueError(f"frame knob {name}: {text!r} is not on or off")
        return BOOL_WORDS[t]
    if name == "camera":
        names = {n.lower(): n for n in cameras()}  # registered names differ in more than case
        if t not in names:
            raise ValueError(f"frame knob camera: {text!r} is not one of {', '.join(names.values())} (the models "
                             f"the pinhole reference can judge)")
        return names[t]
    if name in ("spp", "msaa", "iterations"):
        try:
            v = int(t)
        except ValueError:
            v = None
        low, high = (1, MAX_SPP) if name == "spp" else DENOISE_ITERATIONS.bounds
        allowed = MSAA.choices if name == "msaa" else range(low, high + 1)
        if v is None or v not in allowed:
            what = ", ".join(map(str, MSAA.choices)) if name == "msaa" else f"a whole number from {low} to {high}"
            raise ValueError(f"frame knob {name}: {text!r} is not {what}")
        return v
    try:
        v = float(t)
    except ValueError:
        v = math.nan
    if not SCALES[0] <= v <= SCALES[1]:
        raise ValueError(f"frame knob scale: {text!r} is not a number from {SCALES[0]:g} to {SCALES[1]:g}")
    return v


def parse_grid(text: str | None, base: FrameKnobs = DEFAULT_KNOBS) -> list[FrameKnobs]:
    """`"stereo=dual,reuse;spp=1,4"` -> every combination (knobs not named as in `base`: the
    command's own settings); None or "" -> [base]. ValueError with one line naming what is wrong."""
    names = [f.name for f in fields(FrameKnobs)]
    values: dict = {}
    for part in (text or "").split(";"):
        if not part.strip():
            continue
        name, eq, rest = part.partition("=")
        name = name.strip().lower()
        if not eq or name not in names:
            raise ValueError(f"frame knobs: {part.strip()!r} is not KNOB=VALUE[,VALUE...] with a knob of "
                             f"{', '.join(names)}")
        if name in values:
            raise ValueError(f"frame knobs: {name} is given twice")
        got = [_one(name, v) for v in rest.split(",") if v.strip()]
        if not got:
            raise ValueError(f"frame knobs: {name} has no values")
        values[name] = list(dict.fromkeys(got))
    axes = [values.get(n, [getattr(base, n)]) for n in names]
    points = (FrameKnobs(**dict(zip(names, combo))) for combo in itertools.product(*axes))
    # without the denoiser its iterations change nothing: one point, not one per count
    return list(dict.fromkeys(k if k.denoise else replace(k, iterations=DEFAULT_KNOBS.iterations) for k in points))


def budget_ms_of(hz: float) -> float:
    """A display rate's frame time: 90 Hz -> 11.1 ms."""
    return 1000.0 / hz
