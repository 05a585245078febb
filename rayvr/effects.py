"""Moved to rayvr.frame.effects (rayvr's modules in packages by layer). Kept for code written against the old path
(docs/architecture.md 'Add an effect': from rayvr.effects import Effect, Param, register): its names
resolve here with a DeprecationWarning.
"""


def __getattr__(name):
    """A name of the module that was rayvr.effects before rayvr's modules moved into packages by layer, from where it is now,
    with a DeprecationWarning (lazily: importing this module imports nothing)."""
    import importlib
    import pkgutil
    import warnings

    if name.startswith("__") or name in {m.name for m in pkgutil.iter_modules(globals().get("__path__", []))}:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module("rayvr.frame.effects"), name)
    warnings.warn(f"rayvr.effects.{name} moved to rayvr.frame.effects.{name}", DeprecationWarning, stacklevel=2)
    return value
