"""Material-ID config files (TOML); the effects they name come from the registry (rayvr/frame/effects/).

A config maps a scene's materials to an effect, by exact name, by numeric material index, or
by glob, with per-effect parameters:

    default = "raster"            # effect for materials nothing below matches
    denoise = ["glossy"]          # effects the denoiser filters when it is on (default: the sampled ones)

    [params.shadows]              # defaults for every material using `shadows`
    area_samples = 4

    [materials]
    "floor"    = "shadows"                              # exact name
    "mirror*"  = { effect = "reflections", bounces = 3 } # glob, with parameters
    "face"     = { effect = "shadows", importance = 4.0 }  # weight in --budget-ms choices

    [ids]
    7 = "shadows"                 # numeric material index (as `rayvr info SCENE` lists them)

    [render]                      # render options (`rayvr options` lists them); CLI flags override them
    exposure = 1.5
    stereo = "reuse"

Precedence: exact name, then numeric id, then the first matching glob in file order.
The file is data, never code. Every error names the file, the key and the allowed values;
names that match no material warn with the scene's material names. An effect that rayvr does
not implement yet fails at load time: it never renders silently as `raster`. Parameters are
checked against the effect's own declaration (type, range).
"""
from __future__ import annotations

import fnmatch
import logging
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .. import options, settings
from ..frame.effects import BACKGROUND_EFFECT, EFFECTS, PLANNED, EffectError, effect_by_id, implemented_effects  # noqa: F401
from ..util.inputs import InputFileError, read_text

log = logging.getLogger(__name__)


ECHO_LIMIT = 80  # characters of a key or value that an error message shows
MAX_CONFIG_BYTES = 1 << 20  # a material config is a few hundred bytes; refuse 1 MiB before reading it


def short(text: str) -> str:
    """`text` (a key, or the repr of a value) cut to ECHO_LIMIT characters with an ellipsis: a
    10 MB string in a config must not become a 10 MB error message."""
    text = str(text)
    return text if len(text) <= ECHO_LIMIT else text[:ECHO_LIMIT - 1] + "\u2026"


def _effect_list() -> str:
    planned = [e for e in PLANNED if e not in EFFECTS]
    return ", ".join(EFFECTS) + (f" (not yet: {', '.join(planned)})" if planned else "")


class ConfigError(ValueError):
    """A material config is invalid; the message names file, key and the allowed values."""


@dataclass(frozen=True)
class Assignment:
    effect: str
    params: dict
    rule: str  # which config entry chose it ("default", "materials.floor", "ids.7", ...)
    importance: float = 1.0  # the user's weight for this material's error (budget mode)

    @property
    def effect_id(self) -> int:
        return EFFECTS[self.effect].id


@dataclass
class MaterialConfig:
    """A validated config. `assign(names)` gives one Assignment per scene material."""

    default: str = "raster"
    params: dict = field(default_factory=dict)  # effect -> {param: value}
    by_name: dict = field(default_factory=dict)  # name or glob -> (effect, params)
    by_id: dict = field(default_factory=dict)  # int -> (effect, params)
    importance_of: dict = field(default_factory=dict)  # rule ("materials.x", "ids.3") -> weight
    source: str = "<defaults>"
    denoise: tuple | None = None  # effects the denoiser filters (None: the traced effects marked `denoised`)
    render: dict = field(default_factory=dict)  # [render]: render option -> value (rayvr/options.py), checked

    def effect_params(self, effect: str, overrides: dict | None = None) -> dict:
        spec = EFFECTS[effect].params
        out = {k: p.default for k, p in spec.items()}
        out.update(self.params.get(effect, {}))
        out.update(overrides or {})
        return out

    def assign(self, material_names: list[str], warn: bool = True) -> list[Assignment]:
        result = []
        used_keys = set()
        for index, name in enumerate(material_names):
            if name in self.by_name and not _is_glob(name):
                key, (effect, over) = f"materials.{name}", self.by_name[name]
            elif index in self.by_id:
                key, (effect, over) = f"ids.{index}", self.by_id[index]
            else:
                glob = next((g for g in self.by_name if _is_glob(g) and fnmatch.fnmatchcase(name, g)), None)
                if glob is not None:
                    key, (effect, over) = f"materials.{glob}", self.by_name[glob]
                else:
                    key, effect, over = "default", self.default, {}
            used_keys.add(key)
            result.append(Assignment(effect, self.effect_params(effect, over), key, self.importance_of.get(key, 1.0)))
        for effect in dict.fromkeys(a.effect for a in result):  # frame parameters: one value each (Param.reduce)
            users = [(name, a.params) for name, a in zip(material_names, result) if a.effect == effect]
            try:
                EFFECTS[effect].frame_values(users)
            except EffectError as exc:
                raise ConfigError(f"{self.source}: {exc}") from None
        if warn:
            unused = [f"materials.{k}" for k in self.by_name if f"materials.{k}" not in used_keys]
            unused += [f"ids.{k}" for k in self.by_id if f"ids.{k}" not in used_keys]
            if unused:
                log.warning("%s: %s %s no material in this scene%s; its materials are: %s", self.source,
                            ", ".join(map(short, unused)), "matches" if len(unused) == 1 else "match",
                            near_names(unused, material_names), ", ".join(map(short, material_names)))
        return result

    def unmatched(self, material_names: list[str]) -> list[str]:
        """Config keys that select no material of the scene."""
        out = [k for k in self.by_name if not any(
            (fnmatch.fnmatchcase(n, k) if _is_glob(k) else n == k) for n in material_names)]
        out += [str(k) for k in self.by_id if k >= len(material_names)]
        return out


def config_with(base: MaterialConfig, default: str | None = None, materials: dict | None = None,
                params: dict | None = None) -> MaterialConfig:
    """A copy of `base` with another default effect, per-material effects and effect params."""
    cfg = MaterialConfig(default=default or base.default, params={k: dict(v) for k, v in base.params.items()},
                         by_name=dict(base.by_name), by_id=dict(base.by_id), importance_of=dict(base.importance_of),
                         source=f"{base.source} (variant)", denoise=base.denoise, render=dict(base.render))
    for name, effect in (materials or {}).items():
        cfg.by_name[name] = (effect, {})
    for effect, values in (params or {}).items():
        cfg.params.setdefault(effect, {}).update(values)
        # Per-material parameters win over [params]: a swept value must reach those too.
        for table in (cfg.by_name, cfg.by_id):
            for key, (e, p) in table.items():
                if e == effect:
                    table[key] = (e, {**p, **values})
    return cfg


def _is_glob(s: str) -> bool:
    return any(c in s for c in "*?[")


def _check_effect(value, where: str, source: str) -> str:
    if not isinstance(value, str):
        raise ConfigError(f"{source}: {where}: effect must be a string, got {type(value).__name__} "
                          f"{short(repr(value))}; allowed: {_effect_list()}")
    if value in PLANNED and value not in EFFECTS:
        raise ConfigError(f"{source}: {where}: effect {value!r} ({PLANNED[value]}) is not implemented yet in "
                          f"this rayvr; implemented: {', '.join(EFFECTS)}")
    if value not in EFFECTS:
        raise ConfigError(f"{source}: {where}: unknown effect {short(repr(value))}; allowed: {_effect_list()}")
    return value


def _check_params(effect: str, params: dict, where: str, source: str) -> dict:
    spec = EFFECTS[effect].params
    out = {}
    for key, value in params.items():
        if key not in spec:
            allowed = ", ".join(spec) or "none"
            raise ConfigError(f"{source}: {where}.{short(key)}: unknown parameter for effect {effect!r}; "
                              f"allowed: {allowed}")
        p = spec[key]
        ok = isinstance(value, p.kind) and not isinstance(value, bool)
        if p.kind is float and isinstance(value, int) and not isinstance(value, bool):
            value, ok = float(value), True
        if not ok:
            raise ConfigError(f"{source}: {where}.{key}: expected {p.kind.__name__}, got "
                              f"{type(value).__name__} {short(repr(value))}")
        if p.kind is float and not math.isfinite(value):
            raise ConfigError(f"{source}: {where}.{key}: expected a finite number, got {short(repr(value))}")
        if (p.lo is not None and value < p.lo) or (p.hi is not None and value > p.hi):
            raise ConfigError(f"{source}: {where}.{key}: {short(repr(value))} is outside the allowed range "
                              f"{p.allowed_range()}")
        out[key] = value
    return out


def _parse_entry(value, where: str, source: str) -> tuple[str, dict, float]:
    """(effect, params, importance) of one [materials] / [ids] entry."""
    if isinstance(value, str):
        return _check_effect(value, where, source), {}, 1.0
    if isinstance(value, dict):
        if "effect" not in value:
            raise ConfigError(f"{source}: {where}: a table needs an 'effect' key; allowed effects: {_effect_list()}")
        effect = _check_effect(value["effect"], f"{where}.effect", source)
        importance = value.get("importance", 1.0)
        if isinstance(importance, bool) or not isinstance(importance, (int, float)) or not importance >= 0:
            raise ConfigError(f"{source}: {where}.importance: expected a number >= 0, got {short(repr(importance))}")
        rest = {k: v for k, v in value.items() if k not in ("effect", "importance")}
        return effect, _check_params(effect, rest, where, source), float(importance)
    raise ConfigError(f"{source}: {where}: expected an effect name or a table, got {type(value).__name__}")


TOP_LEVEL_KEYS = ("default", "params", "materials", "ids", "denoise", options.TABLE)


def _check_denoise(value, source: str) -> tuple:
    """`denoise = ["glossy", ...]`: the traced effects whose pixels the denoiser filters."""
    traced = [e.name for e in EFFECTS.values() if e.traced]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{source}: denoise: expected a list of effect names; allowed: {', '.join(traced)}")
    for v in value:
        if v not in traced:
            raise ConfigError(f"{source}: denoise: {short(repr(v))} is not a sampled (traced) effect; "
                              f"allowed: {', '.join(traced)}")
    return tuple(dict.fromkeys(value))


def parse_config(data: dict, source: str = "<config>") -> MaterialConfig:
    """Validate an already-parsed TOML document."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: the document must be a table")
    for key in data:
        if key not in TOP_LEVEL_KEYS:
            raise ConfigError(f"{source}: {short(key)}: unknown top-level key; allowed: {', '.join(TOP_LEVEL_KEYS)}")
    cfg = MaterialConfig(source=source)
    cfg.default = _check_effect(data.get("default", "raster"), "default", source)
    params = data.get("params", {})
    if not isinstance(params, dict):
        raise ConfigError(f"{source}: params: expected a table of [params.<effect>] tables")
    for effect, values in params.items():
        if effect not in EFFECTS:
            raise ConfigError(f"{source}: params.{short(effect)}: unknown effect; allowed: {_effect_list()}")
        if not isinstance(values, dict):
            raise ConfigError(f"{source}: params.{effect}: expected a table")
        cfg.params[effect] = _check_params(effect, values, f"params.{effect}", source)
    mats = data.get("materials", {})
    if not isinstance(mats, dict):
        raise ConfigError(f"{source}: materials: expected a table of name = effect entries")
    for name, value in mats.items():
        effect, params_, importance = _parse_entry(value, f"materials.{short(name)}", source)
        cfg.by_name[name] = (effect, params_)
        cfg.importance_of[f"materials.{name}"] = importance
    if "denoise" in data:
        cfg.denoise = _check_denoise(data["denoise"], source)
    if options.TABLE in data:
        try:
            cfg.render = settings.parse_table(data[options.TABLE], source)
        except options.OptionError as exc:
            raise ConfigError(str(exc)) from None
    ids = data.get("ids", {})
    if not isinstance(ids, dict):
        raise ConfigError(f"{source}: ids: expected a table of index = effect entries")
    for key, value in ids.items():
        try:
            index = int(key)
        except ValueError:
            raise ConfigError(f"{source}: ids.{short(key)}: keys must be non-negative integers (material indices)") \
                from None
        if index < 0:
            raise ConfigError(f"{source}: ids.{short(key)}: keys must be non-negative integers (material indices)")
        effect, params_, importance = _parse_entry(value, f"ids.{short(key)}", source)
        cfg.by_id[index] = (effect, params_)
        cfg.importance_of[f"ids.{index}"] = importance
    return cfg


def near_names(keys: list[str], material_names: list[str]) -> str:
    """' (did you mean floor?)' for config keys (`materials.flor`) close to a material's name."""
    import difflib

    guesses = [g for k in keys if k.startswith("materials.")
               for g in difflib.get_close_matches(k.split(".", 1)[1], material_names, n=1, cutoff=0.75)]
    return f" (did you mean {', '.join(map(short, dict.fromkeys(guesses)))}?)" if guesses else ""


def shipped_hint(path: Path) -> str:
    """For a bare file name that is neither here nor shipped (a misspelt `raster.toml`): the names of
    the configs rayvr ships, which commands take by name alone."""
    from .loader import ASSETS_DIR

    if path.name != str(path) or path.exists():
        return ""
    names = sorted(p.name for p in ASSETS_DIR.glob("*.toml"))
    return f" (rayvr ships {', '.join(names)}, taken by name alone)" if names else ""


def load_config(path: str | Path | None) -> MaterialConfig:
    """Read and validate a TOML material config; None gives the all-`raster` default."""
    if path is None:
        return MaterialConfig()
    path = Path(path)
    try:
        text = read_text(path, "material config", MAX_CONFIG_BYTES)
    except InputFileError as exc:
        raise ConfigError(str(exc) + shipped_hint(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from exc
    except RecursionError:  # tomllib recurses once per level of nested arrays / inline tables
        raise ConfigError(f"{path}: material config nested too deeply (arrays or tables hundreds of levels "
                          f"inside each other)") from None
    return parse_config(data, str(path))
