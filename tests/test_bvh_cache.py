"""The SBVH kept on disk between runs (accel/bvh_cache.py through accel/scene.py kept_scene_bvh)."""
from __future__ import annotations

import logging
from collections import OrderedDict

import numpy as np
import pytest

from rayvr.accel import bvh_cache
from rayvr.accel import scene as accel_scene
from rayvr.accel.bvh import Bvh
from rayvr.scene import from_arrays

TREE = ("node_lo", "node_hi", "left", "right", "start", "count", "depth", "prim_ids", "indices")


def slab_scene(n=200, seed=3, name="slabs"):
    """Long thin diagonal triangles (an SBVH build of some seconds would be cached the same)."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-4, 4, (n, 3))
    v = np.stack([a, a + rng.normal(size=(n, 3)) * 3, a + rng.normal(size=(n, 3)) * 0.05], 1)
    return from_arrays(v.reshape(-1, 3).astype(np.float32), np.arange(3 * n).reshape(n, 3), name=name)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A fresh cache folder and an empty per-process cache."""
    monkeypatch.setenv(bvh_cache.ENV, str(tmp_path / "bvh"))
    monkeypatch.setattr(accel_scene, "_kept", OrderedDict())
    return tmp_path / "bvh"


def forget(monkeypatch):
    monkeypatch.setattr(accel_scene, "_kept", OrderedDict())


def no_build(monkeypatch):
    def fail(*a, **k):
        raise AssertionError("built again instead of loading the cache")
    monkeypatch.setattr(accel_scene, "build_scene_bvh", fail)


def test_an_sbvh_is_built_once_then_loaded_from_disk(cache, monkeypatch):
    scene = slab_scene()
    built = accel_scene.kept_scene_bvh(scene, "sbvh")
    files = list(cache.glob("sbvh-*.npz"))
    assert len(files) == 1
    forget(monkeypatch)
    no_build(monkeypatch)
    loaded = accel_scene.kept_scene_bvh(scene, "sbvh")
    assert all(np.array_equal(getattr(built, k), getattr(loaded, k)) for k in TREE)
    assert np.array_equal(loaded.vertices, scene.vertices) and loaded.params == built.params
    assert not list(cache.glob(".bvh-*"))  # no temporary file left


def test_the_key_follows_geometry_build_and_defaults(monkeypatch):
    def key_of(scene, build):
        return accel_scene.cache_key(accel_scene.geometry_digest(scene.vertices, scene.indices), build)

    a, b = slab_scene(seed=3), slab_scene(seed=4)
    assert key_of(a, "sbvh") != key_of(b, "sbvh")
    assert key_of(a, "sbvh") != key_of(a, "sah")
    key = key_of(a, "sbvh")
    assert key == key_of(slab_scene(seed=3, name="renamed"), "sbvh")  # triangles, not names
    monkeypatch.setattr(bvh_cache, "FORMAT", bvh_cache.FORMAT + 1)
    assert key_of(a, "sbvh") != key


def test_sah_builds_and_a_cache_turned_off_write_nothing(cache, monkeypatch):
    accel_scene.kept_scene_bvh(slab_scene(), "sah")
    assert not cache.exists()
    monkeypatch.setenv(bvh_cache.ENV, "off")
    forget(monkeypatch)
    accel_scene.kept_scene_bvh(slab_scene(), "sbvh")
    assert not cache.exists() and bvh_cache.cache_dir() is None


def test_a_broken_file_is_rebuilt_and_replaced(cache, monkeypatch, caplog):
    scene = slab_scene()
    accel_scene.kept_scene_bvh(scene, "sbvh")
    (path,) = cache.glob("sbvh-*.npz")
    good = path.read_bytes()
    path.write_bytes(good[: len(good) // 2])          # truncated, as by a crash mid-copy
    forget(monkeypatch)
    with caplog.at_level(logging.WARNING, logger="rayvr.accel.bvh_cache"):
        again = accel_scene.kept_scene_bvh(scene, "sbvh")
    assert "unreadable" in caplog.text and isinstance(again, Bvh)
    forget(monkeypatch)
    no_build(monkeypatch)
    accel_scene.kept_scene_bvh(scene, "sbvh")         # the replacement loads


def test_an_unwritable_folder_costs_only_the_saving(tmp_path, monkeypatch, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(bvh_cache.ENV, str(blocker / "bvh"))
    forget(monkeypatch)
    with caplog.at_level(logging.WARNING, logger="rayvr.accel.bvh_cache"):
        bvh = accel_scene.kept_scene_bvh(slab_scene(), "sbvh")
    assert bvh.reference_count >= bvh.triangle_count and "cannot write" in caplog.text


def test_the_default_folder_is_the_user_cache(monkeypatch, tmp_path):
    monkeypatch.delenv(bvh_cache.ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert bvh_cache.cache_dir() == tmp_path / "rayvr" / "bvh"
