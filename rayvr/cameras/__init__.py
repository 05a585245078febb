"""Camera models: how an eye turns pixels into rays (numpy reference + GLSL), chosen by name.

Only the pinhole can be rasterized; any other model (lens-distorted sample lists, spherical
wide views, foveated, thin lens: one module each, added to CAMERA_MODELS) forces ray-cast
primary visibility. See base.py for the contract.
"""
from __future__ import annotations

from .base import CameraModel, CameraRays
from .pinhole import Pinhole

CAMERA_MODELS: dict[str, type[CameraModel]] = {m.name: m for m in (Pinhole,)}


def get_camera_model(name: str, **params) -> CameraModel:
    """The model registered as `name`, built with `params`."""
    try:
        cls = CAMERA_MODELS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown camera model {name!r}; allowed: {', '.join(CAMERA_MODELS)}") from None
    return cls(**params)


__all__ = ["CAMERA_MODELS", "CameraModel", "CameraRays", "Pinhole", "get_camera_model"]
