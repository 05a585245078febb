"""Optional packages (pyproject's extras): a missing one is one error naming the extra that brings
it, raised before any work where a command knows it will need it; the CLI prints it as one line."""
from __future__ import annotations

import importlib

# module -> (package name on PyPI, rayvr extra that installs it)
EXTRAS = {"flip_evaluator": ("flip-evaluator", "bench"), "mitsuba": ("mitsuba", "reference")}

class MissingExtraError(ImportError):
    """An optional package a command needs is not installed."""


def require(module: str, purpose: str):
    """The module `module` (a key of EXTRAS), or MissingExtraError saying what needs it and how to
    install it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        package, extra = EXTRAS[module]
        raise MissingExtraError(f"{purpose} needs the optional '{package}' package: "
                                f"pip install 'rayvr[{extra}]'") from None
