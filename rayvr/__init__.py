"""rayvr: hybrid raster + compute-shader ray tracing for stereo VR, effects chosen per material."""
from .frame.cameras.rig import EyeView, Pose, StereoRig
from .gl.context import ContextError, create_context
from .scene.materials import ConfigError, MaterialConfig, load_config
from .renderer import Frame, Renderer, RenderSettings
from .scene.loader import Scene, SceneError, load

__version__ = "0.1.0"
__all__ = ["Renderer", "RenderSettings", "Frame", "StereoRig", "Pose", "EyeView", "Scene", "SceneError",
           "load", "MaterialConfig", "load_config", "ConfigError", "create_context", "ContextError"]
