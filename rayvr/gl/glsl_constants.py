"""Constants the shaders share with the Python module that declares them, gathered into the
generated header (rayvr/gl/gpu_layout.py glsl_header, `#include "layout.glsl"`).

A module declares a constant once, where Python uses it, and the header emits it:

    ON_LEAF = declare("QT_ON_LEAF", 2.0 ** -18)     # -> #define QT_ON_LEAF 3.814697265625e-06

This module imports nothing from rayvr, so any module (an effect, a camera model, a pass, a
plugin outside rayvr) may declare without an import cycle. A shader sees the constants of the
modules imported when it is compiled: the module that compiles a shader imports the owners of the
constants it uses (a missing one is a compile error naming the constant, never a silent default).
"""
from __future__ import annotations

import numpy as np

CONSTANTS: dict[str, str] = {}  # GLSL name -> its literal, in declaration order


def literal(value, uint: bool = False) -> str:
    """`value` as an exact GLSL literal: ints as ints (`u` for uint), floats so that they round-trip
    (Python floats by repr, numpy float32 by its shortest float32 repr)."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{value!r}: a shader constant is an int or a float, not a bool")
    if isinstance(value, (int, np.integer)):
        v = int(value)
        if not uint:
            return str(v) if v >= 0 else f"({v})"  # "x-NAME" must not read as "x--1"
        if v < 0:
            raise ValueError(f"{v}: a uint constant cannot be negative")
        return f"0x{v:X}u" if v > 0xFFFF else f"{v}u"
    if isinstance(value, (float, np.floating)):
        if uint:
            raise TypeError(f"{value!r}: a uint constant must be an int")
        if not np.isfinite(value):
            raise ValueError(f"{value!r}: GLSL has no literal for a non-finite float")
        text = str(value) if isinstance(value, np.float32) else repr(float(value))
        text = text if any(c in text for c in ".e") else text + ".0"
        return text if not text.startswith("-") else f"({text})"
    raise TypeError(f"{value!r}: a shader constant is an int or a float")


def declare(name: str, value, uint: bool = False):
    """Emit `#define name value` in the generated header; returns `value` for the module's own use."""
    text = literal(value, uint)
    if CONSTANTS.get(name, text) != text:
        raise ValueError(f"shader constant {name} declared twice: {CONSTANTS[name]} and {text}")
    CONSTANTS[name] = text
    return value


def glsl_lines() -> list[str]:
    return [f"#define {name} {text}" for name, text in CONSTANTS.items()]
