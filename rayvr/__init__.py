"""rayvr: hybrid raster + compute-shader ray tracing for stereo VR, effects chosen per material.

The names below load on first use, so that importing a light module of the package (rayvr.options,
rayvr.settings) does not load the renderer and the GL."""
import importlib

__version__ = "0.1.0"
_EXPORTS = {"EyeView": "frame.cameras.rig", "Pose": "frame.cameras.rig", "StereoRig": "frame.cameras.rig",
            "ContextError": "gl.context", "create_context": "gl.context",
            "ConfigError": "scene.materials", "MaterialConfig": "scene.materials", "load_config": "scene.materials",
            "Frame": "renderer", "Renderer": "renderer", "RenderSettings": "renderer",
            "Scene": "scene.loader", "SceneError": "scene.loader", "load": "scene.loader"}
__all__ = ["Renderer", "RenderSettings", "Frame", "StereoRig", "Pose", "EyeView", "Scene", "SceneError",
           "load", "MaterialConfig", "load_config", "ConfigError", "create_context", "ContextError"]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'rayvr' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + __all__)
