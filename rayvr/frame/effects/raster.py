"""`raster`: direct light from the G-buffer, no shadows (the `shade` pass; rect lights by a fixed
4x4 grid of points). Every scene has it: it is the bottom of the ladder and the budget baseline."""
from ..effect_registry import Effect, register


class Raster(Effect):
    name = "raster"
    doc = "direct light from the G-buffer, no shadows"
    reference = {"mirror": 0, "glossy": 0, "diffuse": 0}


register(Raster())
