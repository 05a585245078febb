"""The frame's passes, one per file (each beside its shaders under rayvr/glsl/). Effects add
their own passes (rayvr/effects/); these are the core ones the graph picks from."""


def core_passes() -> list:
    from .bvh import BvhPass
    from .classify import ClassifyPass
    from .debug_view import DebugViewPass
    from .gbuffer_resolve import GBufferResolvePass
    from .primary_rays import PrimaryRaysPass
    from .quadtree import QuadtreePass, QuadtreeVisitsPass
    from .shade import ShadePass
    from .tonemap import TonemapPass
    from .visibility import VisibilityPass

    return [BvhPass(), VisibilityPass(), PrimaryRaysPass(), GBufferResolvePass(), ShadePass(), ClassifyPass(),
            TonemapPass(), DebugViewPass(), QuadtreeVisitsPass(), QuadtreePass(effect="ssr")]
