"""RenderSettings: one field per render option, collected from the modules that declare them
(rayvr/options.py; docs/options.md); and what needs every option at once: the flags of a command,
a config's [render] table, the values a command runs with.

OWNERS are the modules that declare rayvr's options (rayvr/render_options/: they import nothing
heavy, so neither does this module), imported here by name (their order is the fields' order); an
option declared elsewhere later (a plugin's) takes part too, its value kept in RenderSettings.more.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

from . import options
from .options import TABLE, Option, OptionError
from .render_options import (accumulate, accumulation, bvh_build, denoise, dof, light_selection, persistent_threads,
                             primary_rays, quadtree, ray_order, sampling, second_layer, shade, stereo, tonemap, traversal,
                             visibility)

OWNERS = (tonemap, shade, visibility, primary_rays, accumulation, accumulate, denoise, second_layer, stereo, quadtree,
          traversal, bvh_build, dof, sampling, light_selection, ray_order, persistent_threads)
RANK = {m.__name__: i for i, m in enumerate(OWNERS)}
_ordered: list = [None, {}]  # (the declarations, all_options()' answer to them)


def all_options() -> dict[str, Option]:
    """Every declared option by name: by OWNERS (whichever owner a process imported first), then
    any other declarer's (a plugin's, a test's), each in its declaration order."""
    declared = options.declared()
    key = tuple(map(id, declared.values()))
    if _ordered[0] != key:
        ordered = sorted(enumerate(declared.values()), key=lambda io: (RANK.get(io[1].owner, len(RANK)), io[0]))
        _ordered[:] = [key, {o.name: o for _, o in ordered}]
    return _ordered[1]


def for_command(command: str) -> list[Option]:
    return [o for o in all_options().values() if command in o.commands]


def add_arguments(parser, command: str, title: str = "render options") -> None:
    """The flags of every option `command` offers, in one argument group."""
    group = parser.add_argument_group(title)
    for option in for_command(command):
        option.add_to(group)


def given_by_args(args, command: str) -> dict:
    """The options whose flags `args` holds (those left unset are not in it)."""
    return {o.name: getattr(args, o.name) for o in for_command(command) if getattr(args, o.name, None) is not None}


def merged(*layers: dict) -> dict:
    """Option values of `layers` (a config's [render] table, then the CLI flags: later wins), with
    what each given option implies (--temporal accumulates) where it is not given itself."""
    out: dict = {}
    for layer in layers:
        out.update(layer)
    known = all_options()
    for name, value in list(out.items()):
        if value and name in known:
            for implied, v in known[name].implies:
                out.setdefault(implied, v)
    return out


def parse_table(table, source: str) -> dict:
    """The `[render]` table of a config file: {option: checked value}; one error naming the file,
    the key and (for an unknown key) the allowed names."""
    if not isinstance(table, dict):
        raise OptionError(f"{source}: {TABLE}: expected a table of option = value entries")
    known = all_options()
    out = {}
    for key, value in table.items():
        if key not in known:
            raise OptionError(f"{source}: {TABLE}.{str(key)[:80]}: unknown render option; allowed: {', '.join(known)}")
        try:
            out[key] = known[key].check(value)
        except OptionError as exc:
            where = f"{source}: {TABLE}."  # "render.exposure must be ...", "render.traversal: BVH layout ..."
            raise OptionError(f"{where}{exc}" if str(exc).startswith(key + " ") else f"{where}{key}: {exc}") from None
    return out


def check_all(values: dict) -> dict:
    """Every option's value of `values` checked (a RenderSettings' __post_init__)."""
    known = all_options()
    return {k: known[k].check(v) for k, v in values.items()}


# ------------------------------------------------------------------------------ RenderSettings

def settings_class(cls):
    """Make `cls` a dataclass whose fields are the declared options (type, default), in
    declaration order, checked on construction; `to_dict()` / `from_dict()` give its values as
    JSON-ready data and back. Options declared after the class was made (a plugin's, a test's)
    are keywords and attributes too, their values kept in the field `more`."""
    known = all_options()
    cls.__annotations__ = {**{name: o.type if not o.auto else f"{o.type.__name__} | None"
                              for name, o in known.items()}, "more": dict}
    for name, o in known.items():
        setattr(cls, name, o.default)
    cls.more = field(default_factory=dict, repr=False)  # later declarations' values, by name

    def __post_init__(self):
        for name, value in check_all({n: getattr(self, n) for n in known}).items():
            setattr(self, name, value)
        later = all_options()
        _refuse_unknown([k for k in self.more if k not in later or k in known], later)
        self.more = {k: later[k].check(v) for k, v in self.more.items()}

    def __getattr__(self, name):  # only for what is not a field: a later declaration's value or default
        more = self.__dict__.get("more", {})
        if name in more:
            return more[name]
        option = all_options().get(name)
        if option is None or name in known:
            raise AttributeError(f"{type(self).__name__} has no render option {name!r}")
        return option.default

    def to_dict(self) -> dict:
        """The settings as JSON-ready values (tuples as lists), every option by name."""
        values = {**{n: getattr(self, n) for n in known}, **self.more}
        return {n: list(v) if isinstance(v, tuple) else v for n, v in values.items()}

    @classmethod
    def from_dict(klass, data: dict):
        """Settings from to_dict()'s data (missing options keep their defaults; unknown names are refused)."""
        if not isinstance(data, dict):
            raise OptionError(f"render settings must be a table of option values, got {type(data).__name__}")
        later = all_options()
        _refuse_unknown([k for k in data if k not in later], later)
        return klass(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})

    cls.__post_init__, cls.__getattr__, cls.to_dict, cls.from_dict = __post_init__, __getattr__, to_dict, from_dict
    cls = dataclass(cls)
    _accept_other_names(cls, known, {old: o for o in known.values() for old in o.old_names})
    return cls


def _refuse_unknown(names: list, allowed) -> None:
    if names:
        raise OptionError(f"unknown render option(s) {', '.join(map(str, names))}; allowed: {', '.join(allowed)}")


def _accept_other_names(cls, known: dict, renamed: dict) -> None:
    """Keywords of `cls` beyond its fields: deprecated names of an option (RenderSettings(dof_aperture=...),
    a DeprecationWarning; given, it wins over the option's own, as dataclasses.replace passes both;
    a bad value is named by the keyword it came by), and options declared after `cls` (into `more`).
    The deprecated names are attributes too."""
    init = cls.__init__

    def __init__(self, *args, **kw):
        for old, option in renamed.items():
            if old in kw:
                value = kw.pop(old)
                warnings.warn(f"RenderSettings.{old} is deprecated: use {option.name}", DeprecationWarning,
                              stacklevel=2)
                kw[option.name] = option.check(value, name=old)
        later = all_options()
        extra = {k: kw.pop(k) for k in list(kw) if k in later and k not in known}
        if extra:
            kw["more"] = {**kw.get("more", {}), **extra}
        init(self, *args, **kw)

    for old, option in renamed.items():
        setattr(cls, old, property(lambda self, n=option.name: getattr(self, n),
                                   lambda self, v, n=option.name: setattr(self, n, v),
                                   doc=f"deprecated: {option.name}"))
    cls.__init__ = __init__


@settings_class
class RenderSettings:
    """How a Renderer renders: one field per render option (rayvr/options.py), declared by the
    module that uses it (`rayvr options` lists them: type, default, allowed values, scope, flags).
    `RenderSettings(exposure=2)` checks every value on construction (OptionError, a ValueError);
    `to_dict()` / `from_dict()` carry them through files (the capture's job file)."""
