"""`bvh`: builds and uploads the scene's BVH on first use (rayvr/accel/scene.py). Only passes that
read `bvh` make the graph keep it, so an all-`raster` scene never builds one."""
from __future__ import annotations

from ..graph import External, FramePlan, Pass, write


class BvhPass(Pass):
    name = "bvh"

    def io(self, plan: FramePlan) -> list:
        return [write("bvh", External("scene BVH: binned SAH or SBVH, built once, refit by update_vertices"))]

    def execute(self, fc) -> None:
        # built and uploaded on the first frame only (each layout; again if the build changes)
        fc.accel.ensure(fc.plan.traversal, fc.plan.bvh_build)
