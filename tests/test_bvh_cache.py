"""The SBVH kept on disk between runs (accel/bvh_cache.py through accel/scene.py kept_scene_bvh)."""
from __future__ import annotations

import logging
import os
from collections import OrderedDict

import numpy as np
import pytest

from rayvr.accel import bvh_cache
from rayvr.accel import scene as accel_scene
from rayvr.accel.bvh import Bvh
from rayvr.scene.loader import from_arrays

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


# ------------------------------------------------------------------ files that are not their key's tree

def rewrite(path, redo_checksum=True, **changes):
    """Rewrite a cache file with some entries changed; with `redo_checksum` its checksum is made to
    match the new contents (a file that looks right: only the tree checks can tell)."""
    with np.load(path) as f:
        entries = {k: f[k] for k in f.files}
    entries.update(changes)
    if redo_checksum and "checksum" in entries:
        entries["checksum"] = np.str_(bvh_cache.payload_digest(str(entries["key"]), str(entries["params"]),
                                                               {k: entries[k] for k in TREE}))
    np.savez(path, **entries)


def bigger(a, by=1):
    return a + np.asarray(by, a.dtype)


TAMPERED = {  # name: entries of the stored tree -> the changes to write
    "prim_ids zeroed, checksum stale": lambda t: dict(prim_ids=np.zeros_like(t["prim_ids"]), redo_checksum=False),
    "prim_ids zeroed, checksum redone": lambda t: dict(prim_ids=np.zeros_like(t["prim_ids"])),
    "prim_ids beyond the triangles": lambda t: dict(prim_ids=bigger(t["prim_ids"], 10**6)),
    "a child beyond the nodes": lambda t: dict(right=np.where(t["right"] >= 0, bigger(t["right"], 10**6), -1)),
    "a child pointing back (a cycle)": lambda t: dict(left=np.where(t["left"] >= 0, 0, -1).astype(np.int32)),
    "count one short": lambda t: dict(count=t["count"][:-1]),
    "leaf ranges past the slots": lambda t: dict(start=np.where(t["left"] < 0, bigger(t["start"], 5), 0)),
    "vertex indices beyond the vertices": lambda t: dict(indices=bigger(t["indices"], 10**6)),
    "depths off by one": lambda t: dict(depth=bigger(t["depth"])),
    "NaN boxes": lambda t: dict(node_lo=np.full_like(t["node_lo"], np.nan)),
    "float64 boxes": lambda t: dict(node_lo=t["node_lo"].astype(np.float64)),
    "pickled parameters": lambda t: dict(params=np.array([{"bins": 16}], dtype=object), redo_checksum=False),
}


@pytest.mark.parametrize("case", TAMPERED)
def test_a_file_that_is_not_its_keys_tree_is_rebuilt_with_one_warning(cache, monkeypatch, caplog, case):
    scene = slab_scene()
    built = accel_scene.kept_scene_bvh(scene, "sbvh")
    (path,) = cache.glob("sbvh-*.npz")
    with np.load(path) as f:
        stored = {k: f[k] for k in TREE}
    rewrite(path, **TAMPERED[case](stored))
    forget(monkeypatch)
    with caplog.at_level(logging.WARNING, logger="rayvr"):
        again = accel_scene.kept_scene_bvh(scene, "sbvh")
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "building it again" in warnings[0], warnings
    assert str(path) in warnings[0] and "\n" not in warnings[0] and "allow_pickle" not in warnings[0]
    assert all(np.array_equal(getattr(again, k), getattr(built, k)) for k in TREE)  # the right tree, rebuilt
    forget(monkeypatch)
    no_build(monkeypatch)
    accel_scene.kept_scene_bvh(scene, "sbvh")  # and the file replaced by a good one


def test_the_tree_of_another_scene_under_this_key_is_rebuilt(cache, monkeypatch, caplog):
    scene, other = slab_scene(seed=3), slab_scene(seed=4)  # the same sizes, other triangles
    built = accel_scene.kept_scene_bvh(scene, "sbvh")
    (path,) = cache.glob("sbvh-*.npz")
    bvh_cache.store("sbvh-other", accel_scene.build_scene_bvh(other, "sbvh"))
    os.replace(cache / "sbvh-other.npz", path)  # a well-formed file with a good checksum, of another key
    forget(monkeypatch)
    with caplog.at_level(logging.WARNING, logger="rayvr"):
        again = accel_scene.kept_scene_bvh(scene, "sbvh")
    assert "another key" in caplog.text and len(caplog.records) == 1
    assert all(np.array_equal(getattr(again, k), getattr(built, k)) for k in TREE)


@pytest.mark.parametrize("case", ["prim_ids zeroed, checksum redone", "a child beyond the nodes"])
def test_a_capture_over_a_tampered_cache_file_renders_the_right_image(cache, monkeypatch, tmp_path, caplog, case):
    """The issue's cases: every slot made triangle 0 (a wrong image, exit 0), and arrays whose
    indices run past the nodes (an IndexError traceback)."""
    from PIL import Image

    from rayvr.cli import main

    def capture(out):
        assert main(["capture", "--size", "32x24", "--eye", "left", "--bvh-build", "sbvh", "--primary", "rays",
                     "--out", str(out), "-q"]) == 0
        return np.asarray(Image.open(out / "frame_left.png"))

    fresh = capture(tmp_path / "fresh")
    (path,) = cache.glob("sbvh-*.npz")
    with np.load(path) as f:
        rewrite(path, **TAMPERED[case]({k: f[k] for k in TREE}))
    forget(monkeypatch)
    with caplog.at_level(logging.WARNING, logger="rayvr"):
        again = capture(tmp_path / "again")
    assert np.array_equal(again, fresh) and "building it again" in caplog.text
