"""Render options, each declared once for the module that uses it (as Falcor's pass properties or
Mitsuba's plugin properties), in its light twin under rayvr/render_options/: the tonemap pass's
`exposure` and `tonemapper`, the primary-ray pass's `primary` and `tile_culling`, the stereo
module's `stereo` and `warp_layers`, ...

    EXPOSURE = declare(Option("exposure", float, 1.0, "linear scale before tonemapping",
                              bounds=(0, 1e6), lo_open=True, commands=("capture", "preview")))

From the declarations come, with nothing else to write (rayvr/settings.py collects them):
- `RenderSettings`' fields, defaults and validation (`Option.check`, one message style);
- the CLI flags of every command that offers an option (`Option.add_to`; help from `doc`);
- the `[render]` table of a materials TOML (rayvr/scene/materials.py);
- `to_dict` / `from_dict` (the capture's job file) and the listing of `rayvr options` (`listing`).

An option's `scope` says what it changes: "plan" options select passes or programs: each reaches
one FramePlan field (`plan_field`; Renderer.plan applies the owner's policy, e.g.
frame/passes/primary_rays.py primary_visibility), and the FramePlan keys the compiled graphs, so a change
compiles another graph; "frame" options are values the passes read each frame (uniforms) and never
change the plan; "material" options take part in every material's shading (ambient light).
tests/test_options.py checks both directions for every declared option.

This module imports nothing from rayvr (the lowest layer): the owners (rayvr/render_options/) import it.
"""
from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, fields
from typing import Any, Callable

SCOPES = ("plan", "frame", "material")
COMMANDS = ("capture", "preview", "info", "bench")
TABLE = "render"  # the materials TOML table that sets render options


class OptionError(ValueError):
    """A render option's value is not allowed; the message names the option and what is."""


@dataclass(frozen=True)
class Option:
    """One render option: what it takes, what it does, who offers it (docs/options.md)."""

    name: str  # the RenderSettings field and the TOML key
    type: type  # bool, int, float, str or tuple (the value's Python type)
    default: Any
    doc: str  # one sentence: the CLI help, the `rayvr options` listing
    scope: str = "frame"  # SCOPES
    plan_field: str = ""  # scope "plan": the FramePlan field (the compiled graphs' key) its value reaches
    bounds: tuple | None = None  # (lo, hi) of a number, inclusive unless lo_open
    lo_open: bool = False
    choices: tuple | None = None
    label: str = ""  # the noun an unknown choice is named by ("unknown BVH build 'kd'"); default: name
    commands: tuple = ()  # the CLI commands that offer it as a flag (COMMANDS)
    flag: str = ""  # its CLI spelling (default --name-with-dashes)
    deprecated_flags: tuple = ()  # older spellings still accepted (the help says which is current)
    metavar: str | None = None
    convert: Callable | None = None  # value (or CLI/TOML text) -> value, raising ValueError: custom types
    auto: bool = False  # None is a value too: chosen per frame ("auto")
    implies: tuple = ()  # (option, value) pairs set too when this one is given truthy and they are not
    old_names: tuple = ()  # deprecated RenderSettings keywords / attributes still accepted for it
    owner: str = ""  # the module that declared it (filled in by `declare`)

    def __post_init__(self):
        if self.scope not in SCOPES:
            raise ValueError(f"option {self.name}: scope must be one of {', '.join(SCOPES)}, got {self.scope!r}")
        if (self.scope == "plan") != bool(self.plan_field):
            raise ValueError(f"option {self.name}: a plan option names the FramePlan field it reaches (plan_field), "
                             f"no other option does")
        unknown = [c for c in self.commands if c not in COMMANDS]
        if unknown:
            raise ValueError(f"option {self.name}: unknown command(s) {', '.join(unknown)}; allowed: "
                             f"{', '.join(COMMANDS)}")
        self.check(self.default)  # a declaration whose default it refuses is a bug, found at import

    # -- validation: the one place, the one message style ----------------------------------
    @property
    def cli_flag(self) -> str:
        return self.flag or "--" + self.name.replace("_", "-")

    def allowed(self) -> str:
        """What the option takes, in words: "(0, 1e+06]", "1..6", "one of aces, ...", "true or false"."""
        if self.choices is not None:
            return "one of " + ", ".join(map(str, self.choices))
        if self.type is bool:
            return "true or false" + (" (or unset: auto)" if self.auto else "")
        if self.bounds is not None:
            lo, hi = self.bounds
            return f"{lo}..{hi}" if self.type is int else _interval(lo, hi, self.lo_open)
        return self.metavar or self.type.__name__

    def check(self, value, name: str | None = None):
        """`value` as the option's type, or OptionError: "<name> must be ..., got <value>" (`name`:
        another name the value was given by, a deprecated one)."""
        who = name or self.name
        if value is None and self.auto:
            return None
        if self.convert is not None:
            try:
                return self.convert(value)
            except OptionError:
                raise
            except (ValueError, TypeError) as exc:
                raise OptionError(str(exc)) from None
        if self.type is bool:
            if not (isinstance(value, bool) or type(value).__name__ in ("bool_", "bool")):  # numpy's too
                raise OptionError(f"{who} must be {self.allowed()}, got {value!r}")
            return bool(value)
        if self.type is int:
            value = self._whole(value, who)
        elif self.type is float:
            value = self._number(value, who)
        if self.choices is not None and value not in self.choices:
            raise OptionError(f"unknown {self.label or self.name} {value!r}; allowed: "
                              f"{', '.join(map(str, self.choices))}")
        return value

    def _whole(self, value, who: str) -> int:
        span = f" from {self.bounds[0]} to {self.bounds[1]}" if self.bounds is not None else ""
        if isinstance(value, bool) or not _is_int(value):
            raise OptionError(f"{who} must be a whole number{span}, got {value!r}")
        value = int(value)
        if self.bounds is not None and not self.bounds[0] <= value <= self.bounds[1]:
            raise OptionError(f"{who} must be a whole number{span}, got {value}")
        return value

    def _number(self, value, who: str) -> float:
        legal = _interval(*self.bounds, self.lo_open) if self.bounds is not None else "(-inf, inf)"
        if isinstance(value, bool) or not _is_number(value):
            raise OptionError(f"{who} must be a number in {legal}, got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            raise OptionError(f"{who} must be a finite number in {legal}, got {value!r}")
        if self.bounds is not None:
            lo, hi = self.bounds
            if not ((v > lo if self.lo_open else v >= lo) and v <= hi):
                raise OptionError(f"{who} must be in {legal}, got {value!r}")
        return v

    def from_text(self, text: str):
        """The value of a CLI argument's text (numbers and on/off words parsed, then checked)."""
        if self.convert is None and self.type is bool:
            if text.strip().lower() not in BOOL_WORDS:
                raise OptionError(f"{self.name} is on or off, got {text!r}")
            return BOOL_WORDS[text.strip().lower()]
        if self.convert is None and self.type in (int, float):
            try:
                value = self.type(text)
            except ValueError:
                value = text  # check() names it as what it is not
            return self.check(value)
        return self.check(text)

    # -- the CLI ------------------------------------------------------------------------
    def add_to(self, parser) -> None:
        """This option's flag on `parser`; unset, it stays None (the config or the default then)."""
        spellings = [self.cli_flag, *self.deprecated_flags]
        help_ = self.doc + self._help_default()
        if self.deprecated_flags:
            help_ += f"; {', '.join(self.deprecated_flags)}: deprecated spelling of {self.cli_flag}"
        help_ = help_.replace("%", "%%")
        if self.type is bool and (self.auto or self.default):  # on by default: --no-NAME turns it off
            parser.add_argument(*spellings, dest=self.name, action=argparse.BooleanOptionalAction, default=None,
                                help=help_)
        elif self.type is bool:
            parser.add_argument(*spellings, dest=self.name, action="store_const", const=True, default=None,
                                help=help_)
        else:
            metavar = self.metavar or ("{" + ",".join(map(str, self.choices)) + "}" if self.choices
                                       else self.cli_flag.lstrip("-").replace("-", "_").upper())
            parser.add_argument(*spellings, dest=self.name, type=_argparse_type(self), default=None,
                                metavar=metavar, help=help_)

    def _help_default(self) -> str:
        if self.type is bool:
            return " (default: auto)" if self.auto else (" (default: on)" if self.default else "")
        default = ",".join(map(str, self.default)) if isinstance(self.default, tuple) else self.default
        return f" (default {default})"

    def describe(self) -> dict:
        """The `rayvr options` entry."""
        default = list(self.default) if isinstance(self.default, tuple) else self.default
        return {"name": self.name, "type": self.type.__name__, "default": default, "allowed": self.allowed(),
                "scope": self.scope, "plan_field": self.plan_field or None, "commands": list(self.commands),
                "flag": self.cli_flag if self.commands else None, "deprecated_flags": list(self.deprecated_flags),
                "owner": self.owner, "doc": self.doc}


def _interval(lo, hi, lo_open: bool) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"


# The words a switch's text may be (bench vr --variants, the budget's frame knobs).
BOOL_WORDS = {"true": True, "on": True, "yes": True, "1": True, "false": False, "off": False, "no": False, "0": False}


def _is_int(value) -> bool:
    return isinstance(value, int) or type(value).__name__.startswith(("int", "uint"))  # numpy integers too


def _is_number(value) -> bool:
    return _is_int(value) or isinstance(value, float) or type(value).__name__.startswith("float")


def _argparse_type(option: Option):
    def parse(text: str):
        try:
            return option.from_text(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return parse


# ----------------------------------------------------------------------------- plan refusals

class PlanRefusal(ValueError):
    """A frame plan that the options given cannot make. `reason` says why in words of the renderer
    (no flag); `advice` ("leave out" or "use") and `options`, (option, value) pairs, what would make
    it: the API's message names them as keywords (tile_culling=False), `in_flags()` as the command
    line spells them (--no-tile-culling), so the core never names a flag."""

    def __init__(self, reason: str, advice: str = "", *options: tuple):
        self.reason, self.advice, self.options = reason, advice, options
        words = " and ".join(f"{name}={value!r}" for name, value in options)
        super().__init__(f"{reason}: {advice} {words}" if options else reason)

    def in_flags(self) -> str:
        """The refusal as the command line says it: "...: leave out --no-tile-culling"."""
        if not self.options:
            return self.reason
        return f"{self.reason}: {self.advice} " + " and ".join(flag_words(n, v) for n, v in self.options)


def flag_words(name: str, value) -> str:
    """How the command line gives option `name` the value `value`: --msaa 4, --no-tile-culling,
    --temporal (its flag; a name no option has stays as it is)."""
    option = _REGISTRY.get(name)
    flag = option.cli_flag if option is not None else "--" + name.replace("_", "-")
    if isinstance(value, bool) or (option is not None and option.type is bool):
        return flag if value else "--no-" + flag[2:]
    text = ",".join(map(str, value)) if isinstance(value, (tuple, list)) else str(value)
    return f"{flag} {text}"


# ----------------------------------------------------------------------------- plan parts

@dataclass(frozen=True)
class PlanAsk:
    """What a frame plan is made for: the settings, the camera model, the view and eyes, and what
    the scene's materials ask (Renderer.plan fills it)."""

    settings: Any
    camera: Any  # a rayvr.frame.cameras model
    view: str = "color"
    eyes: int = 2
    accumulate: bool = False  # a running mean of samples was asked for (render(spp=N))
    effects: frozenset = frozenset()  # the effects the materials use
    denoised: frozenset = frozenset()  # the effects the config's `denoise` key names
    depth_layers: int = 1  # depth layers the materials' effects need

    @property
    def color(self) -> bool:
        return self.view == "color"


_PLAN_PARTS: dict[str, tuple[Callable, tuple]] = {}


def plan_part(name: str, after: tuple = ()):
    """Register `fn(ask, plan)` as the owner `name`'s part of the frame plan: it adds its FramePlan
    fields to `plan` (the fields of the parts named in `after`, which run before it, and of the
    renderer's frame: effects, view, camera, ...) or raises PlanRefusal. A plan option no part fills
    reaches its plan_field as it is."""
    def register(fn):
        if name in _PLAN_PARTS and _PLAN_PARTS[name][0].__qualname__ != fn.__qualname__:
            raise ValueError(f"plan part {name!r} is registered twice")
        _PLAN_PARTS[name] = (fn, tuple(after))
        return fn
    return register


def _ordered_parts() -> list[Callable]:
    """The parts with each one after those it names (registration order otherwise)."""
    done, out = set(), []

    def visit(name, path=()):
        if name in done or name not in _PLAN_PARTS:
            return
        if name in path:
            raise ValueError(f"plan parts name each other in a loop: {' -> '.join(path + (name,))}")
        for before in _PLAN_PARTS[name][1]:
            visit(before, path + (name,))
        done.add(name)
        out.append(_PLAN_PARTS[name][0])
    for name in list(_PLAN_PARTS):
        visit(name)
    return out


def remove_plan_part(name: str) -> None:
    """Forget a plan part (tests that register a toy one)."""
    _PLAN_PARTS.pop(name, None)


def plan_fields(ask: PlanAsk, frame: dict) -> dict:
    """The frame plan's fields: `frame`'s (the renderer's: effects, view, camera, ...), every owner's
    part, then the plan options no part filled."""
    plan = dict(frame)
    for fn in _ordered_parts():
        fn(ask, plan)
    for option in _REGISTRY.values():
        if option.scope == "plan" and option.plan_field not in plan:
            plan[option.plan_field] = getattr(ask.settings, option.name)
    return plan


# ------------------------------------------------------------------------------- the registry

_REGISTRY: dict[str, Option] = {}


def declare(option: Option, owner: str | None = None) -> Option:
    """Register `option`; its owner is `owner`, else the declaring module (the caller's __name__)."""
    if option.name in _REGISTRY:
        raise ValueError(f"render option {option.name!r} is declared twice ({_REGISTRY[option.name].owner} and "
                         f"{owner or option.owner})")
    if owner is None and not option.owner:
        import sys

        owner = sys._getframe(1).f_globals.get("__name__", "")
    if owner:
        option = _replace(option, owner=owner)
    _REGISTRY[option.name] = option
    return option


def remove(name: str) -> None:
    """Forget a declaration (tests that declare a toy option)."""
    _REGISTRY.pop(name, None)


def _replace(option: Option, **kw) -> Option:
    return Option(**{**{f.name: getattr(option, f.name) for f in fields(Option)}, **kw})


def declared() -> dict[str, Option]:
    """The options declared so far, in declaration order (rayvr/settings.py's all_options() has
    them all, in their owners' order)."""
    return dict(_REGISTRY)


# ----------------------------------------------------------------------------- the listing

def listing(options: list[Option]) -> str:
    """`rayvr options`: each option with its flag, type, default, allowed values, scope, commands and doc."""
    lines = []
    for o in options:
        d = o.describe()
        default = ",".join(map(str, d["default"])) if isinstance(d["default"], list) else d["default"]
        flag = d["flag"] or "(no flag)"
        if d["deprecated_flags"]:
            flag += f" (also {', '.join(d['deprecated_flags'])}, deprecated)"
        lines.append(f"{o.name}  {flag}")
        scope = f"plan (FramePlan.{o.plan_field})" if o.plan_field else o.scope
        lines.append(f"    {d['type']}, default {default}, {d['allowed']}; scope {scope}; "
                     f"commands: {', '.join(o.commands) or 'none (API and [render] only)'}; declared in {o.owner}")
        lines.append(f"    {o.doc}")
    return "\n".join(lines) + "\n"
