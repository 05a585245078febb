"""The effect ladder as plugins: one module per effect, registered by name (see ../effect_registry.py,
whose names this package re-exports for plugins)."""
from ..effect_registry import (BACKGROUND_EFFECT, EFFECTS, MAX_EFFECT_ID, PARAM_WORDS, PLANNED, Effect, EffectError,
                               Param, effect_by_id, get, implemented_effects, register, traced_effects, unregister)
from . import raster, shadows, ssr, reflections, glossy, path, photon  # noqa: F401  (the built-in rungs register themselves)

__all__ = ["BACKGROUND_EFFECT", "EFFECTS", "MAX_EFFECT_ID", "PARAM_WORDS", "PLANNED", "Effect", "EffectError",
           "Param", "effect_by_id", "get", "implemented_effects", "register", "traced_effects", "unregister"]
