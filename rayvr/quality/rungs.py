"""The rungs a budget pick chooses from, per material: each effect of the ladder with the base
config's parameters, and, with `--rung-params "glossy.samples=1,4;path.samples=1,4"`, an effect
with one of its per-material parameters set. A rung is named by a key: the effect ("glossy"), or
the effect with its setting ("glossy(samples=4)"); a pick's assignment names keys, and
measure.config_for_assignment turns each back into its effect and parameters.
"""
from __future__ import annotations

from ..scene.materials import EFFECTS, implemented_effects


def rung_key(effect: str, param: str | None = None, value=None) -> str:
    return effect if param is None else f"{effect}({param}={value})"


def parse_rung(key: str) -> tuple[str, dict]:
    """A rung key -> (effect, {param: value}); ValueError naming the key where it is not one."""
    effect, paren, rest = key.partition("(")
    if not paren:
        return key, {}
    param, eq, value = rest.rstrip(")").partition("=")
    spec = EFFECTS.get(effect)
    if not rest.endswith(")") or not eq or spec is None or param not in spec.params:
        raise ValueError(f"rung {key!r} is not EFFECT or EFFECT(PARAM=VALUE) with a parameter of the effect")
    return effect, {param: _value(spec.params[param], value)}


def _value(spec, text: str):
    return spec.kind(float(text)) if spec.kind is float else spec.kind(text)


def parse_rung_params(text: str | None) -> list[str]:
    """`"glossy.samples=1,4;path.samples=1,4"` -> the rung keys they add to the ladder's own (in
    that order); None or "" -> []. ValueError with one line naming what is wrong."""
    keys = []
    for part in (text or "").split(";"):
        if not part.strip():
            continue
        name, eq, values = part.partition("=")
        effect, dot, param = name.strip().partition(".")
        if not eq or not dot:
            raise ValueError(f"rung params: {part.strip()!r} is not EFFECT.PARAM=VALUE[,VALUE...]")
        if effect not in implemented_effects():
            raise ValueError(f"rung params: {effect!r} is not an effect; choose from {', '.join(implemented_effects())}")
        spec = EFFECTS[effect].params.get(param)
        if spec is None:
            raise ValueError(f"rung params: {effect} has no parameter {param!r}; it has "
                             f"{', '.join(EFFECTS[effect].params) or 'none'}")
        if spec.scope != "material":
            raise ValueError(f"rung params: {effect}.{param} is one value for the whole frame, not a material's")
        for text_value in (v.strip() for v in values.split(",") if v.strip()):
            try:
                value = _value(spec, text_value)
            except ValueError:
                raise ValueError(f"rung params: {effect}.{param}={text_value!r} is not a{'n integer' if spec.kind is int else ' number'}") from None
            if spec.clamp(value) != value:
                raise ValueError(f"rung params: {effect}.{param}={text_value} is outside {spec.allowed_range()}")
            keys.append(rung_key(effect, param, value))
    if (text or "").strip() and not keys:
        raise ValueError("rung params: no values")
    return list(dict.fromkeys(keys))


def budget_rungs(text: str | None) -> list[str] | None:
    """The rungs of `--rung-params`: the ladder's effects, then the settings it adds; None without it."""
    extra = parse_rung_params(text)
    return list(implemented_effects()) + extra if extra else None
