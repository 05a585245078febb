"""One frame from a plan: the graph of passes and its resources (G-buffer), the passes, the effects
that add them, the cameras (the stereo rig and the camera models), the stereo modes, sample
accumulation and the readback of the images.

`rayvr.frame` was a module before: its names still resolve here, with a DeprecationWarning
(docs/architecture.md 'Add a pass': from rayvr.frame import Pass, Texture, read, write).
"""


def __getattr__(name):
    """A name of the module that was rayvr.frame before rayvr's modules moved into packages by layer, from where it is now,
    with a DeprecationWarning (lazily: importing this package imports nothing)."""
    import importlib
    import pkgutil
    import warnings

    if name.startswith("__") or name in {m.name for m in pkgutil.iter_modules(globals().get("__path__", []))}:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module("rayvr.frame.graph"), name)
    warnings.warn(f"rayvr.frame.{name} moved to rayvr.frame.graph.{name}", DeprecationWarning, stacklevel=2)
    return value
