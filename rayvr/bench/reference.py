"""Reference images: the most accurate setting rayvr has for a scene.

Every material gets the top rung of the effect ladder that models it, restricted to what
`implemented_effects()` offers now (the ladder grows; the reference grows with it):

* mirror (metallic, roughness < MIRROR_ROUGHNESS)       -> `reflections`, many bounces
* glossy (rough metal, or a dielectric with roughness
  <= GLOSSY_DIELECTRIC_ROUGHNESS: a visible GGX lobe)    -> `glossy`, many samples
* everything else                                        -> `shadows`, many area-light samples

An effect that is not implemented falls back down the ladder (a mirror to `glossy`, then
`shadows`, then `raster`), never up to something that models it wrongly (a glossy surface is
never rendered as a perfect mirror). `path` (when implemented and asked for) replaces all of it.

`reference_settings()` gives RenderSettings for comparisons with other renderers: no ambient
term (it stands in for indirect light, which no direct-light reference has), black background,
exposure 1.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..materials import EFFECTS, MaterialConfig, implemented_effects, parse_config

MIRROR_ROUGHNESS = 0.05
GLOSSY_DIELECTRIC_ROUGHNESS = 0.5

# Quality of the reference; each is clamped to the effect parameter's allowed range.
REFERENCE_QUALITY = {"bounces": 8, "samples": 256, "area_samples": 256, "path_samples": 1024}
QUICK_QUALITY = {"bounces": 2, "samples": 16, "area_samples": 16, "path_samples": 64}

# Fallback chains, best first: each step still models the material (only less of it).
_CHAINS = {
    "mirror": ("reflections", "glossy", "shadows", "raster"),
    "glossy": ("glossy", "shadows", "raster"),
    "diffuse": ("shadows", "raster"),
}


def material_class(material) -> str:
    """'mirror', 'glossy' or 'diffuse' from rayvr's metallic-roughness parameters."""
    if material.metallic >= 0.5:
        return "mirror" if material.roughness < MIRROR_ROUGHNESS else "glossy"
    return "glossy" if material.roughness <= GLOSSY_DIELECTRIC_ROUGHNESS else "diffuse"


def _clamp(effect: str, key: str, value):
    p = EFFECTS[effect].params[key]
    if p.lo is not None:
        value = max(value, p.kind(p.lo))
    if p.hi is not None:
        value = min(value, p.kind(p.hi))
    return p.kind(value)


def _params(effect: str, q: dict) -> dict:
    want = {"reflections": {"bounces": q["bounces"], "area_samples": q["area_samples"]},
            "glossy": {"samples": q["samples"], "bounces": q["bounces"], "area_samples": q["area_samples"]},
            "shadows": {"area_samples": q["area_samples"]},
            "path": {"samples": q["path_samples"], "bounces": q["bounces"]},
            "raster": {}}[effect]
    return {k: _clamp(effect, k, v) for k, v in want.items() if k in EFFECTS[effect].params}


@dataclass(frozen=True)
class ReferenceChoice:
    material: str
    kind: str  # mirror | glossy | diffuse
    wanted: str  # the effect the reference would use if every effect were implemented
    effect: str  # what it uses now
    params: dict


def reference_choices(scene, quick: bool = False, use_path: bool = False,
                      available=None, quality: dict | None = None) -> list[ReferenceChoice]:
    """One choice per scene material (index order). `available` defaults to implemented_effects();
    `quality` overrides entries of REFERENCE_QUALITY/QUICK_QUALITY (e.g. {"bounces": 1})."""
    have = set(implemented_effects() if available is None else available)
    q = {**(QUICK_QUALITY if quick else REFERENCE_QUALITY), **(quality or {})}
    out = []
    for m in scene.materials:
        kind = material_class(m)
        chain = _CHAINS[kind]
        if use_path and "path" in have:
            chain = ("path",) + chain
        effect = next((e for e in chain if e in have), "raster")
        out.append(ReferenceChoice(m.name, kind, chain[0], effect, _params(effect, q)))
    return out


def reference_config(scene, quick: bool = False, use_path: bool = False, available=None,
                     quality: dict | None = None) -> MaterialConfig:
    """A validated MaterialConfig giving each material its reference effect. Entries are keyed
    by material index ([ids]) so names with glob characters cannot match other materials."""
    return config_from_choices(reference_choices(scene, quick, use_path, available, quality))


def config_from_choices(choices: list[ReferenceChoice]) -> MaterialConfig:
    data = {"default": "raster",
            "ids": {str(i): {"effect": c.effect, **c.params} for i, c in enumerate(choices)}}
    return parse_config(data, "<reference>")


def reference_settings(**overrides):
    """RenderSettings for comparisons: no ambient, black background, exposure 1, clamp tonemap
    (comparisons read the linear HDR target, so the tonemapper only affects the PNGs)."""
    from ..renderer import RenderSettings

    kw = {"ambient": (0.0, 0.0, 0.0), "background": (0.0, 0.0, 0.0), "exposure": 1.0, "tonemapper": "clamp"}
    kw.update(overrides)
    return RenderSettings(**kw)


def describe(choices: list[ReferenceChoice]) -> dict:
    """{material: "effect(params)"} for a report's meta, noting fallbacks."""
    out = {}
    for c in choices:
        args = ", ".join(f"{k}={v}" for k, v in c.params.items())
        s = f"{c.effect}({args})" if args else c.effect
        if c.effect != c.wanted:
            s += f" [wants {c.wanted}: not implemented yet]"
        out[c.material] = f"{c.kind}: {s}"
    return out
