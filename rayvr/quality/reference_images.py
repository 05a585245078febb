"""Reference images: the most accurate setting rayvr has for a scene.

Every material is put in a class and gets the registered effect that ranks highest for that
class (each effect declares its place: `Effect.reference`, rayvr/frame/effects/), at reference quality
(`Effect.reference_params`). With today's effects `path` ranks first for every class (many paths,
full global illumination); without it (`available`, e.g. a direct-light comparison):

* mirror (metallic, roughness < MIRROR_ROUGHNESS)       -> `reflections`, many bounces
* glossy (rough metal, or a dielectric with roughness
  <= GLOSSY_DIELECTRIC_ROUGHNESS: a visible GGX lobe)    -> `glossy`, many samples
* everything else                                        -> `shadows`, many area-light samples

An effect that is not available falls back down its class's ranking (a mirror to `glossy`,
then `shadows`, then `raster`), never to an effect that does not model the class (a glossy
surface is never rendered as a perfect mirror).

`reference_settings()` gives RenderSettings for comparisons with other renderers: no ambient
term (it stands in for indirect light, which no direct-light reference has), black background,
exposure 1.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..frame.effects import EFFECTS, implemented_effects
from ..frame.effects.ssr import MIRROR_ROUGHNESS
from ..scene.materials import MaterialConfig, parse_config
from ..renderer import RenderSettings

GLOSSY_DIELECTRIC_ROUGHNESS = 0.5

# Quality of the reference; each is clamped to the effect parameter's allowed range.
REFERENCE_QUALITY = {"bounces": 8, "samples": 256, "area_samples": 256, "path_samples": 1024}
QUICK_QUALITY = {"bounces": 2, "samples": 16, "area_samples": 16, "path_samples": 64}



def chain(kind: str) -> tuple:
    """Registered effects that model material class `kind`, best first (each still models it,
    only less of it)."""
    ranked = [e for e in EFFECTS.values() if kind in e.reference]
    return tuple(e.name for e in sorted(ranked, key=lambda e: -e.reference[kind]))


def material_class(material) -> str:
    """'mirror', 'glossy' or 'diffuse' from rayvr's metallic-roughness parameters."""
    if material.metallic >= 0.5:
        return "mirror" if material.roughness < MIRROR_ROUGHNESS else "glossy"
    return "glossy" if material.roughness <= GLOSSY_DIELECTRIC_ROUGHNESS else "diffuse"


@dataclass(frozen=True)
class ReferenceChoice:
    material: str
    kind: str  # mirror | glossy | diffuse
    wanted: str  # the effect the reference would use if every effect were implemented
    effect: str  # what it uses now
    params: dict


def reference_choices(scene, quick: bool = False, available=None, quality: dict | None = None) -> list[ReferenceChoice]:
    """One choice per scene material (index order). `available` defaults to implemented_effects();
    `quality` overrides entries of REFERENCE_QUALITY/QUICK_QUALITY (e.g. {"bounces": 1})."""
    have = set(implemented_effects() if available is None else available)
    q = {**(QUICK_QUALITY if quick else REFERENCE_QUALITY), **(quality or {})}
    out = []
    for m in scene.materials:
        kind = material_class(m)
        best = chain(kind)
        effect = next((e for e in best if e in have), "raster")
        params = EFFECTS[effect].reference_params(q) if effect in EFFECTS else {}
        out.append(ReferenceChoice(m.name, kind, best[0], effect, params))
    return out


def reference_config(scene, quick: bool = False, available=None, quality: dict | None = None) -> MaterialConfig:
    """A validated MaterialConfig giving each material its reference effect. Entries are keyed
    by material index ([ids]) so names with glob characters cannot match other materials."""
    return config_from_choices(reference_choices(scene, quick, available, quality))


def config_from_choices(choices: list[ReferenceChoice]) -> MaterialConfig:
    data = {"default": "raster",
            "ids": {str(i): {"effect": c.effect, **c.params} for i, c in enumerate(choices)}}
    return parse_config(data, "<reference>")


def reference_settings(**overrides):
    """RenderSettings for comparisons: no ambient, black background, exposure 1, clamp tonemap
    (comparisons read the linear HDR target, so the tonemapper only affects the PNGs)."""
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
