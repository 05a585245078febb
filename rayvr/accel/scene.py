"""The scene's BVH as a frame resource: built on first use, uploaded once, refit on request.

Only the `bvh` pass (rayvr/passes/raytrace.py) calls `SceneAccel.ensure()`, and the frame graph
schedules that pass only when a ray-traced effect or ray-traced primary visibility needs it: a
scene that is all `raster` never reaches `build_scene_bvh`. A process keeps its last KEPT_BUILDS
BVHs by geometry and build (`kept_scene_bvh`), so the next Renderer of the same triangles skips the
build, and the builds that take seconds (DISK_BUILDS) are also kept on disk between runs
(accel/bvh_cache.py); `bench bvh` and `bench rays` time builds and call `build_scene_bvh` itself.
"""
from __future__ import annotations

import dataclasses
import hashlib
import inspect
import json
import logging
from collections import OrderedDict

import numpy as np

from . import bvh_cache
from ..util.digest import arrays_digest
from .bvh import BUILDS, Bvh, build_bvh
from .gpu import GpuBvh

log = logging.getLogger(__name__)
KEPT_BUILDS = 4  # BVHs a process keeps for the next Renderer of the same geometry (benchmarks make dozens)
_kept: OrderedDict = OrderedDict()  # (geometry digest, build) -> Bvh, least recently used first
DISK_BUILDS = ("sbvh",)  # kept on disk too: seconds to build (Sponza 5.8 s), a fraction of one to load


def build_scene_bvh(scene, build: str = "sah", progress: bool = True) -> Bvh:
    """BVH over the scene's triangles in scene-local coordinates (the space of the G-buffer's
    positions); hit IDs are the scene's triangle IDs. `build`: "sah" (binned SAH) or "sbvh" (with
    spatial splits, accel/sbvh.py; `progress`: its tqdm bar)."""
    if build not in BUILDS:
        raise ValueError(f"unknown BVH build {build!r}; allowed: {', '.join(BUILDS)}")
    bvh = build_bvh(scene.vertices, scene.indices, spatial_splits=build == "sbvh", progress=progress)
    log.info("%s: %s BVH of %d triangles (%d references) built in %.3f s (SAH cost %.1f)", scene.name, build,
             bvh.triangle_count, bvh.reference_count, bvh.build_seconds, bvh.sah_cost())
    return bvh


def geometry_digest(vertices, indices) -> str:
    """A digest of the triangles (positions and indices, with their dtypes and shapes)."""
    return arrays_digest(vertices, indices)


def cache_key(digest: str, build: str) -> str:
    """The disk cache's name for the BVH of `build` over the triangles of `digest` (geometry_digest):
    those, the build, every default parameter of build_bvh and the file format, so a changed default
    never reads an old tree."""
    defaults = {k: p.default for k, p in inspect.signature(build_bvh).parameters.items()
                if p.default is not inspect.Parameter.empty and k != "progress"}
    h = hashlib.blake2b(digest_size=16)
    h.update(json.dumps([digest, build, defaults, bvh_cache.FORMAT], sort_keys=True).encode())
    return f"{build}-{h.hexdigest()}"


def _loaded_or_built(scene, build: str, digest: str) -> Bvh:
    """build_scene_bvh, through the disk cache for DISK_BUILDS (`digest`: the scene's geometry_digest)."""
    if build not in DISK_BUILDS:
        return build_scene_bvh(scene, build)
    key = cache_key(digest, build)
    bvh = bvh_cache.load(key, scene.vertices, scene.indices)
    if bvh is not None:
        log.info("%s: %s BVH of %d triangles loaded from the BVH cache (%s)", scene.name, build,
                 bvh.triangle_count, bvh_cache.cache_dir())
        return bvh
    bvh = build_scene_bvh(scene, build)
    bvh_cache.store(key, bvh)
    return bvh


def _private_copy(bvh: Bvh) -> Bvh:
    """A Bvh whose arrays the caller may refit in place without touching the kept one."""
    return dataclasses.replace(bvh, **{f.name: getattr(bvh, f.name).copy() for f in dataclasses.fields(bvh)
                                        if isinstance(getattr(bvh, f.name), np.ndarray)})


def kept_scene_bvh(scene, build: str = "sah") -> Bvh:
    """build_scene_bvh, but a BVH this process built for the same triangles and build is reused
    (as a private copy: a refit changes only the caller's): a benchmark's every Renderer of Sponza
    paid the build again, 0.7 s (sah) to 13 s (sbvh). DISK_BUILDS also come from, and go to, the
    disk cache."""
    digest = geometry_digest(scene.vertices, scene.indices)
    key = (digest, build)
    bvh = _kept.get(key)
    if bvh is None:
        bvh = _loaded_or_built(scene, build, digest)
        _kept[key] = _private_copy(bvh)
        while len(_kept) > KEPT_BUILDS:
            _kept.popitem(last=False)
        return bvh
    _kept.move_to_end(key)
    log.info("%s: %s BVH of %d triangles reused (built earlier in this process)", scene.name, build,
             bvh.triangle_count)
    return _private_copy(bvh)


class SceneAccel:
    def __init__(self, gl, scene):
        self.gl, self.scene = gl, scene
        self.bvh: Bvh | None = None
        self.build: str | None = None    # how self.bvh was built (bvh.BUILDS)
        self.gpu: GpuBvh | None = None   # the binary layout (the reference), always there once built
        self.wide: dict[str, GpuBvh] = {}   # the wide layouts a plan's traversal asked for
        self._refit = None

    @property
    def built(self) -> bool:
        return self.gpu is not None

    def ensure(self, layouts=(), build: str = "sah") -> GpuBvh:
        """Build (`build`: bvh.BUILDS) and upload the BVH once; also the wide `layouts` (collapsed from
        it) not made yet. Another `build` than the one made rebuilds from the current positions."""
        if self.gpu is not None and build != self.build:
            self.release()      # the scene's vertices are current (Renderer.update_vertices)
        if self.gpu is None:
            self.bvh = kept_scene_bvh(self.scene, build)
            self.build = build
            self.gpu = GpuBvh(self.gl.ctx, self.bvh)
        for name in layouts:
            if name != "bvh2" and name not in self.wide:
                self.wide[name] = GpuBvh(self.gl.ctx, self.bvh, layout=name)
        return self.gpu

    def layout(self, name: str) -> GpuBvh:
        """The GPU buffers of layout `name` (ensure() made them)."""
        return self.gpu if name == "bvh2" else self.wide[name]

    def refit(self, vertices, on_gpu: bool = False) -> None:
        """Moving geometry (same triangles, new scene-local positions): refit the boxes on the host
        and re-upload, or (`on_gpu`, binary layout alone) refit on the GPU (accel/refit.py; the host
        boxes then go stale).
        A BVH not built yet is simply built from the new positions when first needed."""
        if self.bvh is None:
            return
        v = np.asarray(vertices, np.float32)
        if on_gpu and not self.wide:
            if self._refit is None:
                from .refit import GpuRefit
                self._refit = GpuRefit(self.gl.ctx, self.gpu)
            self._refit.run(v)
        else:   # on the host; wide nodes are always packed there, from the host boxes
            self.bvh.refit(v)
            for g in (self.gpu, *self.wide.values()):
                g.update()

    def release(self) -> None:
        if self._refit is not None:
            self._refit.release()
            self._refit = None
        for g in [self.gpu, *self.wide.values()]:
            if g is not None:
                g.release()
        self.wide = {}
        self.gpu = self.bvh = self.build = None
