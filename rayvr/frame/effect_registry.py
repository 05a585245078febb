"""What an effect is: a rung of the ladder, registered by name (Mitsuba-style plugins).

An effect declares, in one place:
  name, id        the config name; the value the G-buffer's effect channel holds for its pixels
  params          typed parameters (type, range, default, doc, scope): config validation and the
                  GPU parameter block (8 words per material, floats included) are generated from
                  them; a frame-scoped one takes no word: one value per frame, reduced over the
                  materials that use the effect (Param.reduce), reaches its programs as a uniform
  traced          True when its own passes shade its pixels from a pixel list (the `classify`
                  pass lists them; the `shade` pass skips them); False: `shade` lights them
  denoised        (traced effects) whether `--denoise` filters its pixels by default
  passes()        the frame-graph passes it adds (rayvr/frame/passes/); the graph adds what they read
  shader          its GLSL (under rayvr/glsl/, or an absolute path for an effect outside rayvr);
                  for the wavefront effects, the file defining effect_start_paths()
  shader_defines  defines its programs get (LIGHT_MIS: its light samples are weighed by MIS
                  against its BSDF samples, glsl/common/mis.glsl)
  sweep           parameter -> (full, quick) values for `rayvr bench tradeoff`
  reference       material class ("mirror", "glossy", "diffuse") -> rank: the reference image
                  gives each material the highest-ranked registered effect for its class
  reference_params(quality)   its parameters at reference quality

Adding an effect is one module (a subclass, `register(MyEffect())`), its shaders and its test.

The registry sits below the passes (docs/architecture.md, "Layers"): it imports only gpu_layout (and
adds its effect lines to the generated header), so a core pass reads an effect's declared traits
(`traced`, `uses_quadtree`, `reflective`, `path_vertices`, `denoised`, its ID) here without importing
any effect; the built-in rungs, which bring their own passes, register from rayvr/frame/effects/.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from ..gl import gpu_layout
from ..gl.gpu_layout import BACKGROUND_EFFECT, MAX_EFFECT_ID, PARAM_WORDS  # noqa: F401  (the registry's names too)
from ..gl.shaders import declares

PARAM_TYPES = (int, float)
# Where a parameter's value lives: "material", a word of each material's GPU block (the shaders read
# material_param_int/float); "frame", one value per frame for every material of the effect (a
# uniform `param_<name>` of its programs, frame_uniforms), made from theirs by the param's reducer.
PARAM_SCOPES = ("material", "frame")
# A frame-scoped parameter's one value from the values of the materials that use the effect:
# the largest, the smallest, or "agree": they must give the same one (else a config error naming them).
REDUCERS = {"max": max, "min": min, "agree": None}


@dataclass(frozen=True)
class Param:
    kind: type  # int or float
    default: object
    lo: float | None = None
    hi: float | None = None
    doc: str = ""
    scope: str = "material"  # PARAM_SCOPES
    reduce: str | None = None  # frame scope: a REDUCERS key (default "agree"); material scope: None

    def __post_init__(self):
        if self.kind not in PARAM_TYPES:
            raise TypeError(f"effect parameters are int or float, got {self.kind!r}")
        if self.scope not in PARAM_SCOPES:
            raise TypeError(f"an effect parameter's scope is one of {', '.join(PARAM_SCOPES)}, got {self.scope!r}")
        if self.scope == "material" and self.reduce is not None:
            raise TypeError("a material-scoped parameter has a value per material: it takes no reducer")
        if self.scope == "frame":
            object.__setattr__(self, "reduce", self.reduce or "agree")
            if self.reduce not in REDUCERS:
                raise TypeError(f"a frame parameter's reducer is one of {', '.join(REDUCERS)}, got {self.reduce!r}")

    def allowed_range(self) -> str:
        return f"[{'-inf' if self.lo is None else self.lo}, {'inf' if self.hi is None else self.hi}]"

    def clamp(self, value):
        if self.lo is not None:
            value = max(value, self.kind(self.lo))
        if self.hi is not None:
            value = min(value, self.kind(self.hi))
        return self.kind(value)


class Effect:
    name: str = ""
    id: int = -1  # -1: the registry picks the next free ID
    doc: str = ""
    params: dict = {}
    traced: bool = False
    reflective: bool = False  # reflection rays that meet it go on (reflections, glossy)
    path_vertices: bool = False  # its shader shades every hit of its paths itself (path; EFFECT_PATH_VERTEX)
    uses_quadtree: bool = False  # its rays go through the screen-space quadtree first (ssr)
    denoised: bool = True  # traced: the denoiser filters its pixels unless the config's `denoise` key
                           # lists others (False for mirror-like rungs, whose detail is no noise)
    shader: str | None = None
    shader_defines: dict = {}
    sweep: dict = {}
    reference: dict = {}

    def passes(self) -> list:
        return []

    def reference_params(self, quality: dict) -> dict:
        """Parameters at reference quality: every parameter named in `quality`, clamped."""
        return {k: p.clamp(quality[k]) for k, p in self.params.items() if k in quality}

    # -- the GPU parameter block -------------------------------------------------------
    def param_slots(self) -> dict:
        """material-scoped parameter -> word in the material's parameter block (declaration order)."""
        return {k: i for i, k in enumerate(k for k, p in self.params.items() if p.scope == "material")}

    def param_defines(self) -> dict:
        """PARAM_<NAME> = slot, for the effect's own shaders (read with material_param_int/float)."""
        return {f"PARAM_{k.upper()}": i for k, i in self.param_slots().items()}

    def pack_params(self, values: dict) -> np.ndarray:
        """The material's parameter words: ints as int32, floats as float32 bits."""
        words = np.zeros(PARAM_WORDS, np.uint32)
        for k, i in self.param_slots().items():
            v = values.get(k, self.params[k].default)
            fmt = "<i" if self.params[k].kind is int else "<f"
            words[i] = struct.unpack("<I", struct.pack(fmt, v))[0]
        return words

    # -- frame-scoped parameters ---------------------------------------------------------
    def frame_values(self, users) -> dict:
        """The frame's value of each frame-scoped parameter from `users`, (material, its params)
        pairs of the materials that use this effect, by the parameter's reducer (its default
        without users). EffectError naming the materials where an "agree" parameter differs."""
        out = {}
        for k, p in self.params.items():
            if p.scope != "frame":
                continue
            values = {name: params.get(k, p.default) for name, params in users}
            if not values:
                out[k] = p.default
            elif p.reduce == "agree":
                if len(set(values.values())) > 1:
                    given = ", ".join(f"{name} {v!r}" for name, v in values.items())
                    raise EffectError(f"{self.name}.{k} is one value per frame for every material of {self.name}, "
                                      f"and they differ ({given}): give them one value")
                out[k] = next(iter(values.values()))
            else:
                out[k] = REDUCERS[p.reduce](values.values())
        return out

    def frame_uniforms(self, program, users) -> None:
        """Set `program`'s uniform param_<name> of each frame-scoped parameter it declares."""
        for k, v in self.frame_values(users).items():
            if declares(program, f"param_{k}"):
                program[f"param_{k}"].value = v

    def __repr__(self) -> str:
        return f"<effect {self.name} #{self.id}>"


class EffectError(ValueError):
    pass


EFFECTS: dict[str, Effect] = {}  # registration order = ladder order (cheapest first)
# Rungs of the ladder that later versions add: a config naming one is refused as "not yet".
PLANNED: dict[str, str] = {}  # every rung of the ladder is implemented now


def register(effect: Effect) -> Effect:
    """Add an effect to the registry; its ID is the one it declares or the next free one."""
    if not effect.name or not effect.name.isidentifier():
        raise EffectError(f"effect name must be an identifier, got {effect.name!r}")
    if effect.name in EFFECTS:
        raise EffectError(f"effect {effect.name!r} is registered already")
    if len(effect.param_slots()) > PARAM_WORDS:
        raise EffectError(f"effect {effect.name!r}: at most {PARAM_WORDS} material-scoped parameters (its GPU "
                          f"block), got {len(effect.param_slots())}; a value per frame can be scope=\"frame\"")
    used = {e.id for e in EFFECTS.values()}
    if effect.id < 0:
        effect.id = next(i for i in range(MAX_EFFECT_ID + 1) if i not in used)
    if effect.id in used or not 0 <= effect.id < MAX_EFFECT_ID:
        raise EffectError(f"effect {effect.name!r}: ID {effect.id} is taken or outside [0, {MAX_EFFECT_ID})")
    EFFECTS[effect.name] = effect
    return effect


def unregister(name: str) -> None:
    EFFECTS.pop(name, None)


def get(name: str) -> Effect:
    try:
        return EFFECTS[name]
    except KeyError:
        raise EffectError(f"unknown effect {name!r}; allowed: {', '.join(EFFECTS)}") from None


def implemented_effects() -> list[str]:
    return list(EFFECTS)


def traced_effects() -> list[Effect]:
    """Effects with pixel lists, in registration order (= their list slot)."""
    return [e for e in EFFECTS.values() if e.traced]


def effect_by_id(effect_id: int) -> Effect | None:
    return next((e for e in EFFECTS.values() if e.id == effect_id), None)


def _header_lines() -> list[str]:
    """The registry's part of the generated GLSL header: each effect's ID and parameter slots,
    which effects reflection rays go on at, and the pixel-list slot of each traced effect."""
    lines, reflective = [], 0
    for e in EFFECTS.values():
        lines.append(f"#define EFFECT_{e.name.upper()} {e.id}")
        lines += [f"#define PARAM_{e.name.upper()}_{k.upper()} {i}" for k, i in e.param_slots().items()]
        reflective |= (1 << e.id) if e.reflective else 0
    lines.append(f"#define REFLECTIVE_EFFECTS {reflective}u  // bit e: reflection rays go on at effect e")
    traced = traced_effects()
    table = [-1] * MAX_EFFECT_ID
    for slot, e in enumerate(traced):
        table[e.id] = slot
    lines += [f"#define RT_SLOTS {max(len(traced), 1)}  // pixel lists: one per traced effect",
              f"#define RT_SLOT_TABLE int[{MAX_EFFECT_ID}]({', '.join(map(str, table))})  // effect ID -> list, -1: none"]
    return lines


gpu_layout.generated_lines(__name__, _header_lines)
