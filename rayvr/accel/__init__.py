"""Acceleration structures: BVH build/refit/packing (bvh.py) and its GPU side (gpu.py)."""
from .bvh import (Bvh, BufferTooLargeError, build_bvh, intersect_triangles, offset_ray, trace_brute_force,
                  trace_reference)
from .gpu import GpuBvh, Hits, RayTracer, trace_rays

__all__ = ["Bvh", "BufferTooLargeError", "build_bvh", "intersect_triangles", "offset_ray",
           "trace_brute_force", "trace_reference", "GpuBvh", "Hits", "RayTracer", "trace_rays"]
