"""The core passes: every frame graph picks from these (rayvr/renderer.py), and adds the passes of the
plan's effects (Effect.passes())."""
from .accumulate import AccumulatePass
from .bvh import BvhPass
from .classify import ClassifyPass
from .debug_view import DebugViewPass
from .denoise import DenoisePass
from .dof import DofPass
from .gbuffer_resolve import GBufferResolvePass
from .primary_rays import PrimaryRaysPass
from .quadtree import QuadtreePass, QuadtreeVisitsPass
from .reuse import ReuseCopyPass, ReuseMapPass
from .second_layer import SecondLayerPass
from .sample_accumulate import SampleAccumulatePass
from .sample_pattern import SamplePatternPass
from .sample_resolve import SampleResolvePass
from .shade import ShadePass
from .tonemap import TonemapPass
from .visibility import VisibilityPass
from .warp import WarpPass


def core_passes() -> list:
    """One of each core pass; the graph keeps those a plan needs."""
    return [BvhPass(), VisibilityPass(), PrimaryRaysPass(), GBufferResolvePass(), ShadePass(), ClassifyPass(),
            AccumulatePass(), DenoisePass(), TonemapPass(), DebugViewPass(), QuadtreeVisitsPass(),
            QuadtreePass(), SecondLayerPass(), ReuseMapPass(),
            ReuseCopyPass(), WarpPass(), DofPass(), SampleAccumulatePass(), SampleResolvePass(),
            SamplePatternPass()]
