"""Camera models: how an eye turns pixels into rays (numpy reference + GLSL), chosen by name.

Only the pinhole can be rasterized; every other model (lens-distorted per-channel samples,
spherical wide views, foveated patterns, thin lens: one module each, in CAMERA_MODELS) forces
ray-cast primary visibility. See base.py for the contract and register_camera_model (how a model
from outside rayvr is added too), sampling.py for sub-rays.
"""
from __future__ import annotations

import dataclasses

from .base import CAMERA_MODELS, CameraModel, CameraRays, register_camera_model, unregister_camera_model
from .distorted import Distorted
from .foveated import Foveated
from .pinhole import Pinhole
from .thin_lens import ThinLens
from .wide import Wide

for _model in (Pinhole, Distorted, Wide, Foveated, ThinLens):  # their CAMERA_<NAME> ids: 1, 2, ... in this order
    register_camera_model(_model)
DEFAULT_CAMERA_MODEL = Pinhole.name  # what a rig, a frame plan and --camera-model take when none is named


def get_camera_model(name: str, **params) -> CameraModel:
    """The model registered as `name`, built with `params` (its dataclass fields)."""
    try:
        cls = CAMERA_MODELS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown camera model {name!r}; allowed: {', '.join(CAMERA_MODELS)}") from None
    allowed = [f.name for f in dataclasses.fields(cls)]
    unknown = [k for k in params if k not in allowed]
    if unknown:
        raise ValueError(f"camera model {name!r} has no parameter {unknown[0]!r}; "
                         f"allowed: {', '.join(allowed) or 'none'}")
    return cls(**params)


def parse_camera_params(name: str, items) -> dict:
    """`key=value` strings (the CLI's --camera-param) -> typed parameters of model `name`:
    numbers, comma-separated numbers (tuples; '/' separates per-channel triples) or text."""
    if name not in CAMERA_MODELS:
        raise ValueError(f"unknown camera model {name!r}; allowed: {', '.join(CAMERA_MODELS)}")
    fields = {f.name: f for f in dataclasses.fields(CAMERA_MODELS[name])}
    out = {}
    for item in items or ():
        key, sep, text = item.partition("=")
        key = key.strip()
        allowed = ', '.join(fields) or '(none: the ' + name + ' camera has no parameters)'
        if not sep:
            raise ValueError(f"camera parameter {item!r}: expected KEY=VALUE with KEY one of {allowed}")
        if key not in fields:
            raise ValueError(f"camera parameter {item!r}: the {name} camera has no parameter {key!r}; "
                             f"allowed: {allowed}")
        default = fields[key].default
        text = text.strip()
        try:
            if isinstance(default, tuple) and ((default and isinstance(default[0], tuple)) or "/" in text):
                out[key] = tuple(tuple(float(v) for v in part.split(",")) for part in text.split("/"))
            elif isinstance(default, tuple):
                out[key] = tuple(float(v) for v in text.split(","))
            elif isinstance(default, float) or (default is None and "float" in str(fields[key].type)):
                out[key] = float(text)
            else:
                out[key] = text
        except ValueError:
            raise ValueError(f"camera parameter {key}: cannot read {text!r} as "
                             f"{'numbers' if isinstance(default, tuple) else 'a number'}") from None
    return out


__all__ = ["CAMERA_MODELS", "DEFAULT_CAMERA_MODEL", "CameraModel", "CameraRays", "Distorted", "Foveated", "Pinhole",
           "ThinLens", "Wide", "get_camera_model", "parse_camera_params", "register_camera_model",
           "unregister_camera_model"]
