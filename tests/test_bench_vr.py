"""`rayvr bench vr`: the headset's frame on seeded head poses (content and random). The figures come
from the GPU machine; here: the quick run's rows and report, the poses, the refusals."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import quick_bench, run_rayvr

from rayvr.renderer import Renderer, RenderSettings


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """`rayvr bench vr --quick` once for the module: (vr.json, vr.md text)."""
    out = tmp_path_factory.mktemp("vr")
    result = quick_bench("vr", out)
    return result, (out / "vr.md").read_text()


@pytest.fixture(scope="module")
def room():
    from rayvr.scene import loader

    return loader.load(None)


def test_the_quick_bench_times_every_cell_on_every_pose(quick):
    result, md = quick
    meta, rows = result["meta"], result["rows"]
    assert meta["bench"] == "vr" and meta["gl_renderer"] and meta["per_eye_size"] == [32, 24]
    poses = meta["scenes"]["default"]["poses"]
    assert len(poses) == meta["poses"] >= 2
    # the grid the meta names: every camera at every count (the raster G-buffer at 1x only), every config
    expected = {(c, cam, n, p["index"]) for c in meta["configs"] for cam in meta["cameras"] for n in meta["counts"]
                for p in poses if cam != "raster_gbuffer" or n == 1}
    # the quick grid still holds what the rows compare: raster vs rays pinhole, another model, MSAA
    assert {"raster_gbuffer", "pinhole"} < set(meta["cameras"]) and {"shadows", "room"} <= set(meta["configs"])
    assert 1 in meta["counts"] and max(meta["counts"]) > 1
    got = [(r["config"], r["camera"], r["msaa"], r["pose"]["index"]) for r in rows]
    assert sorted(got) == sorted(expected)  # each once
    assert {r["scene"] for r in rows} == {"default"} and {r["variant"] for r in rows} == {"default"}
    for r in rows:
        assert math.isfinite(r["frame_ms"]) and r["frame_ms"] > 0, r
        assert r["passes"] and all(math.isfinite(v) and v >= 0 for v in r["passes"].values()), r
        # the render loop's times: a frame's CPU recording, and the wall time a frame back to back
        assert 0 < r["record_ms"] and 0 < r["pipelined_ms"] and math.isfinite(r["pipelined_ms"]), r
        assert ("visibility" if r["camera"] == "raster_gbuffer" else "primary_rays") in r["passes"]
        assert r["primary"] == ("raster" if r["camera"] == "raster_gbuffer" else "rays")
        assert r["pose"] == poses[r["pose"]["index"]]
    assert "## default" in md and meta["gl_renderer"] in md
    assert "2x32x24" in md


def _md_cells(md: str) -> dict:
    """vr.md's table rows: (scene, config, variant, camera, msaa) -> (median, worst, best, worst pose
    "I (kind)", CPU record / pipelined cell, frame shows (median), frame shows (worst pose))."""
    out, scene = {}, None
    for line in md.splitlines():
        if line.startswith("## "):
            scene = line[3:].strip()
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if scene and line.startswith("|") and len(cells) == 16 and cells[4].isdigit():
            key = (scene, cells[0], cells[1], cells[2], int(cells[4]))
            out[key] = (float(cells[6]), float(cells[7]), float(cells[8]), cells[9], cells[11], cells[14], cells[15])
    return out


def test_the_worst_column_is_the_slowest_pose(quick):
    """vr.md's median / worst / best frame ms of a cell, and its render loop's CPU record / pipelined
    frame medians, recomputed from vr.json's rows of its poses."""
    result, md = quick
    table = _md_cells(md)
    groups: dict = {}
    for r in result["rows"]:
        groups.setdefault((r["scene"], r["config"], r["variant"], r["camera"], r["msaa"]), []).append(r)
    assert set(table) == set(groups)
    for key, rows in groups.items():
        frame = [r["frame_ms"] for r in rows]
        median, worst, best, worst_pose, loop, _, _ = table[key]
        assert worst == pytest.approx(max(frame), abs=6e-4), key
        record, pipelined = (float(v) for v in loop.split(" / "))
        assert record == pytest.approx(float(np.median([r["record_ms"] for r in rows])), abs=6e-4), key
        assert pipelined == pytest.approx(float(np.median([r["pipelined_ms"] for r in rows])), abs=6e-4), key
        assert best == pytest.approx(min(frame), abs=6e-4), key
        assert median == pytest.approx(float(np.median(frame)), abs=6e-4), key
        slowest = max(rows, key=lambda r: r["frame_ms"])["pose"]
        assert worst_pose == f"{slowest['index']} ({slowest['kind']})"  # the headline's pose, and its kind
    assert any(len({r["frame_ms"] for r in rows}) > 1 for rows in groups.values())  # poses really differ


def test_targets_judge_the_worst_pose(quick):
    """The issue's ratio and rate targets, recomputed from vr.json's rows pose by pose."""
    result, md = quick
    by = {t["target"]: t for t in result["meta"]["targets"] if t["variant"] == "default" and t["scene"] == "default"}
    assert {"chromatic_frame", "msaa4_frame", "primary_rate"} <= set(by) and "msaa16_primary" not in by

    def frame(camera, msaa, config, pose):
        return next(r["frame_ms"] for r in result["rows"] if (r["camera"], r["msaa"], r["config"], r["pose"]["index"],
                                                                 r["variant"]) == (camera, msaa, config, pose, "default"))
    poses = {r["pose"]["index"] for r in result["rows"]}
    ratios = [frame("pinhole", 4, c, p) / frame("pinhole", 1, c, p) for c in ("shadows", "room") for p in poses]
    assert by["msaa4_frame"]["worst"] == pytest.approx(max(ratios))
    assert by["msaa4_frame"]["met"] == (max(ratios) <= 1.3)
    w, h = result["meta"]["per_eye_size"]
    rates = [2 * w * h / r["passes"]["primary_rays"] / 1e6 for r in result["rows"]
             if (r["camera"], r["msaa"], r["variant"]) == ("pinhole", 1, "default")]
    assert by["primary_rate"]["worst"] == pytest.approx(min(rates))
    assert "4x MSAA frame <= 1.3x the 1x ray-cast frame" in md
    # each target by name and bound, on the worst pose named with its kind
    assert "Targets, on the worst pose" in md and "Issue" not in md
    kinds = {p["index"]: p["kind"] for p in result["meta"]["scenes"]["default"]["poses"]}
    t = by["msaa4_frame"]
    assert t["worst_pose_label"] == f"{t['worst_pose']} ({kinds[t['worst_pose']]})"
    assert f"| msaa4_frame | 4x MSAA frame <= 1.3x the 1x ray-cast frame | default | {t['worst']:.3f}x | " \
           f"{t['worst_pose_label']}, {t['worst_config']} |" in md


def test_poses_come_back_from_the_seed(quick, room):
    from rayvr.bench.head_poses import draw_poses

    result, _ = quick
    assert result["meta"]["pose_seed"] == 22  # the fixed default
    bench = result["meta"]["scenes"]["default"]["poses"]
    assert [p.to_dict() for p in draw_poses(room, "default", len(bench), 22)] == bench  # what the bench timed
    again, other = draw_poses(room, "default", 8, 22), draw_poses(room, "default", 8, 23)
    assert again == draw_poses(room, "default", 8, 22)
    assert draw_poses(room, "default", 3, 22) == again[:3]  # the count does not move the first poses
    for a, b in zip(again, other):
        assert a.position != b.position and a.yaw_deg != b.yaw_deg and a.pitch_deg != b.pitch_deg


def test_every_row_records_what_its_frame_shows(quick, room, gl):
    """effect_share of each row: shares of the frame's pixels that add up to 1, equal to a count of
    the material ids of the same view read back here, each material's pixels given its config's
    effect; vr.md prints the cell's median over the poses and its worst pose's."""
    from rayvr.bench.head_poses import HeadPose
    from rayvr.bench.primary import CONFIGS
    from rayvr.bench.rays import hybrid_config
    from rayvr.bench.scenes import shipped_config
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene.materials import load_config

    result, md = quick
    meta = result["meta"]
    sm = meta["scenes"]["default"]
    poses = {p["index"]: HeadPose(p["index"], tuple(p["position"]), p["yaw_deg"], p["pitch_deg"], p["kind"])
             for p in sm["poses"]}
    configs = {"shadows": hybrid_config("default"), "room": load_config(shipped_config("default"))}
    names = room.material_names()
    first = {}  # the frame the bench read: the first (variant, msaa) of each (config, camera, pose)
    for r in result["rows"]:
        share = r["effect_share"]
        assert sum(share.values()) == pytest.approx(1.0, abs=1e-6), r
        assert "background" in share and all(v >= 0 for v in share.values())
        first.setdefault((r["config"], r["camera"], r["pose"]["index"]), r)
        assert share == first[(r["config"], r["camera"], r["pose"]["index"])]["effect_share"]
    with Renderer(room, gl=gl) as rr:
        for (config, camera, pose), row in first.items():
            model, fov, primary = CONFIGS[camera]
            rig = StereoRig(poses[pose].pose, ipd=sm["ipd"], fov_y=fov or sm["fov_y"], near=sm["near"],
                            size=tuple(meta["per_eye_size"]), camera=model)
            rr.set_materials(configs[config])
            rr.settings = RenderSettings(primary=primary, msaa=row["msaa"])
            f = rr.render(rig, aux=("material",))
            ids = np.concatenate([f.left.aux["material"].ravel(), f.right.aux["material"].ravel()])
            effect = {i: a.effect for i, a in enumerate(configs[config].assign(names, warn=False))}
            counted = {}
            for i in ids.tolist():
                key = effect.get(i, "background")
                counted[key] = counted.get(key, 0) + 1
            got = {k: v for k, v in row["effect_share"].items() if v > 0}
            assert got == pytest.approx({k: v / ids.size for k, v in counted.items()}, abs=1e-9), (config, camera)
    cells = _md_cells(md)
    shown = {c[5] for c in cells.values()} | {c[6] for c in cells.values()}
    assert all("%" in x for x in shown) and any("background" in x or "shadows" in x for x in shown)


def _eyes_clear_of_triangles(scene, rig_kw, poses) -> None:
    """Every eye lies inside the scene's bounds and at least `near` away from every triangle's box
    (so from every triangle): inside the room, not in a wall, a box or a pillar."""
    from rayvr.frame.cameras.rig import StereoRig

    tris = scene.world_vertices()[scene.indices]
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    bounds = np.asarray(scene.bounds)
    for p in poses:
        rig = StereoRig(p.pose, **rig_kw)
        for eye in rig.eyes():
            e = eye.position
            assert np.all(e > bounds[0] + rig.near) and np.all(e < bounds[1] - rig.near), (p, e)
            gap = np.linalg.norm(np.maximum(np.maximum(lo - e, e - hi), 0.0), axis=1)
            assert gap.min() >= rig.near, (p, e, gap.min())


def _check_orientation(poses) -> None:
    for p in poses:
        r = p.pose.rotation
        assert np.allclose(r.T @ r, np.eye(3), atol=1e-12)
        forward, right = -r[:, 2], r[:, 0]
        pitch = math.degrees(math.asin(forward[1]))
        # random heads look within +-20 degrees of level, content heads at their target within +-60
        assert abs(pitch) <= (20.0 if p.kind == "random" else 60.0) and pitch == pytest.approx(p.pitch_deg, abs=1e-9)
        assert abs(right[1]) < 1e-12  # no roll: the eyes stay level
        yaw = math.degrees(math.atan2(-forward[0], -forward[2])) % 360.0  # 0 along -Z, turning left
        assert yaw == pytest.approx(p.yaw_deg % 360.0, abs=1e-9)
        if p.kind == "content":
            to = np.asarray(p.target) - np.asarray(p.position)
            np.testing.assert_allclose(forward, to / np.linalg.norm(to), atol=1e-9)
    pitches = [p.pitch_deg for p in poses if p.kind == "random"]
    assert min(pitches) < -10 and max(pitches) > 10  # drawn across the range, not one fixed view
    assert {p.kind for p in poses} == {"content", "random"}


def test_room_poses_stay_inside_the_room(room):
    from rayvr.bench.head_poses import draw_poses
    from rayvr.frame.cameras.rig import StereoRig

    poses = draw_poses(room, "default", 128, 22)  # 64 random ones: the 64 of before content poses came
    base = StereoRig.for_scene(room)
    _eyes_clear_of_triangles(room, {"ipd": base.ipd, "near": base.near}, poses)
    _check_orientation(poses)
    heights = [p.position[1] for p in poses]
    assert 1.5 <= min(heights) and max(heights) <= 1.8  # eye height above the room's floor at 0


def test_sponza_poses_stay_inside_the_nave(shared_scene):
    from rayvr.bench.head_poses import draw_poses
    from rayvr.bench.scenes import SCENES
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.scene import loader

    sponza = loader.load(shared_scene(SCENES["sponza"][0]))
    poses = draw_poses(sponza, "sponza", 64, 22)  # 32 random ones: the 32 poses of before content poses came
    base = StereoRig.for_scene(sponza)
    _eyes_clear_of_triangles(sponza, {"ipd": base.ipd, "near": 0.05}, poses)
    _check_orientation(poses)
    # the nave: between the colonnades (pillars from |z| = 2.06 m), above its floor (y = 0.09 m)
    assert all(abs(p.position[2]) < 2.0 and 1.5 < p.position[1] - 0.09 < 1.85 for p in poses)


def test_variants_name_their_rows_and_reach_the_settings(tmp_path, gl):
    """A variant's RenderSettings fields are in the rows timed under its name: the tile culling
    switch here (on by default with MSAA, off in the variant)."""
    from rayvr.bench import vr

    result = vr.run(tmp_path, size=(16, 12), scenes=("default",), poses=1, cameras=("pinhole",), counts=(4,),
                    configs=("shadows",), variants={"default": {}, "per_ray": {"tile_culling": False}}, repeat=1,
                    warmup=1, progress=False, gl=gl)
    culled = {r["variant"]: r["tile_culling"] for r in result["rows"]}
    assert culled == {"default": True, "per_ray": False}
    assert json.loads((tmp_path / "vr.json").read_text())["meta"]["variants"]["per_ray"] == {"tile_culling": False}


def test_the_ssr_config_puts_the_hybrid_frames_mirrors_on_ssr(tmp_path, gl):
    """`--configs ssr`: the hybrid frame with its mirrors (the room's mirror and gold) on `ssr`, the
    rest on shadows, timed under its own name. Through a lens the renderer refuses ssr: that cell is
    named with the refusal, and the others are still measured."""
    from rayvr.bench import vr

    result = vr.run(tmp_path, size=(16, 12), scenes=("default",), poses=1, cameras=("distorted_chromatic", "pinhole"),
                    counts=(1,), configs=("shadows", "ssr"), repeat=1, warmup=1, progress=False, gl=gl)
    rows = {r["config"]: r for r in result["rows"] if r["camera"] == "pinhole"}
    assert set(rows) == {"shadows", "ssr"}
    assert {(r["config"], r["camera"]) for r in result["rows"]} == {("shadows", "distorted_chromatic"),
                                                                     ("shadows", "pinhole"), ("ssr", "pinhole")}
    skipped = result["meta"]["scenes"]["default"]["cells_skipped"]
    assert list(skipped) == ["ssr default distorted_chromatic 1x"] and "not a pinhole" in skipped[
        "ssr default distorted_chromatic 1x"]
    assert "Cell ssr default distorted_chromatic 1x not measured" in (tmp_path / "vr.md").read_text()
    assert "rt_ssr" in rows["ssr"]["passes"] and "rt_reflections" not in rows["ssr"]["passes"]
    assert "rt_reflections" in rows["shadows"]["passes"] and "rt_ssr" not in rows["shadows"]["passes"]
    meta = json.loads((tmp_path / "vr.json").read_text())["meta"]["scenes"]["default"]["configs"]
    assert meta["ssr"]["ssr"] == meta["shadows"]["reflections"] == ["mirror*", "gold"]


def test_the_variants_flag_parses_named_options_and_refuses_bad_ones():
    """--variants "NAME:option=value,...;...": values parsed and checked by their render options,
    each variant on top of the render flags given; a bad spec is one line naming the variant."""
    import argparse

    from rayvr.cli import build_parser
    from rayvr.commands.bench import _variants

    got = _variants("entries:; lists:tile_lists=256 ;blocks:block_culling=on,tile_lists=64")
    assert got == {"entries": {}, "lists": {"tile_lists": 256}, "blocks": {"block_culling": True, "tile_lists": 64}}
    for bad, words in (("lists:tile_lists=100", "lists"), ("x:no_such=1", "render option"),
                       ("a:;a:", "its own name"), ("blocks:block_culling=maybe", "on or off"), (";", "at least one")):
        with pytest.raises(argparse.ArgumentTypeError, match=words):
            _variants(bad)
    args = build_parser().parse_args(["bench", "vr", "--variants", "plain:;lists:tile_lists=64", "--msaa", "4"])
    assert args.variants == {"plain": {}, "lists": {"tile_lists": 64}}


def test_rows_carry_the_primary_visibility_stages(tmp_path, gl):
    """Each ray-cast row times the primary_rays kernels one by one: the tile-list variant's stages
    are the cull, the lists and the trace; the raster row has none."""
    from rayvr.bench import vr

    result = vr.run(tmp_path, size=(16, 12), scenes=("default",), poses=1, cameras=("raster_gbuffer", "pinhole"),
                    counts=(1, 4), configs=("shadows",), variants={"lists": {"tile_lists": 64}}, repeat=1, warmup=1,
                    progress=False, gl=gl)
    stages = {(r["camera"], r["msaa"]): set(r["primary_stages"]) for r in result["rows"]}
    assert stages[("raster_gbuffer", 1)] == set()
    assert {"cull", "lists", "trace", "select"} <= stages[("pinhole", 4)] and "cast" in stages[("pinhole", 1)]
    assert "primary_rays stages" in (tmp_path / "vr.md").read_text()


def test_rows_time_each_round_of_a_sampled_frame(gl):
    """A 4x MSAA row lists, per pass that runs each round, one time per round (the rounds the frame
    ran: the most distinct triangles any pixel's sub-rays hit, as the trace counted them in
    msaa_count); a 1x frame has one round and lists none."""
    from rayvr import Renderer
    from rayvr.bench import vr
    from rayvr.frame.cameras.rig import StereoRig
    from rayvr.renderer import RenderSettings

    with Renderer(None, gl=gl) as r:
        r.set_materials(vr.hybrid_config("default"))
        r.settings = RenderSettings(primary="rays", msaa=4)
        rig = StereoRig.for_scene(r.scene, size=(32, 24))
        row = vr.frame_row(r, rig, 1, 1, 0.0)
        rounds = int(np.frombuffer(r.resource("msaa_count").read(), np.uint32)[0])
        r.settings = RenderSettings(primary="rays")
        assert vr.frame_row(r, rig, 1, 1, 0.0)["round_passes"] == {}
    assert rounds >= 2, "the room at 32x24 has pixels on two triangles"
    assert {"primary_rays", "gbuffer", "rt_shadows", "sample_accumulate"} <= set(row["round_passes"])
    assert all(len(ms) == rounds and min(ms) >= 0 for ms in row["round_passes"].values()), row["round_passes"]


def test_vr_md_lists_each_round_of_the_worst_pose(quick):
    """vr.md names, per cell that runs rounds, its worst pose's ms round by round: the passes' times
    of each round summed (round_totals, checked by hand on a small row), and no line for 1x pinhole."""
    from rayvr.bench.vr import round_totals

    assert round_totals({"round_passes": {"a": [1.0, 2.0], "b": [3.0, 4.0, 5.0]}}) == [4.0, 6.0, 5.0]
    assert round_totals({"round_passes": {}}) == []
    result, md = quick
    listed = {line.split(":")[0] for line in md.splitlines() if line.startswith("- ") and "x: " in line}
    assert "- shadows default pinhole 4x" in listed and "- shadows default pinhole 1x" not in listed
    row = next(r for r in result["rows"] if r["camera"] == "pinhole" and r["msaa"] == 4)
    assert len(round_totals(row)) == len(next(iter(row["round_passes"].values()))) >= 2


def test_a_scenes_first_cell_warms_longest(tmp_path, gl, monkeypatch):
    """The clocks after a scene's build: its first cell's first pose warms SCENE_WARMUP_S at least,
    every other cell's first pose WARMUP_S, the other poses only until times settle."""
    from rayvr.bench import vr

    asked = []
    real = vr.frame_row
    monkeypatch.setattr(vr, "frame_row", lambda r, rig, repeat, warmup, warmup_s:
                        asked.append(warmup_s) or real(r, rig, repeat, warmup, warmup_s))
    vr.run(tmp_path, size=(16, 12), scenes=("default",), poses=2, cameras=("pinhole",), counts=(1, 4),
           configs=("shadows",), repeat=1, warmup=1, progress=False, gl=gl)
    assert asked == [vr.SCENE_WARMUP_S, 0.0, vr.WARMUP_S, 0.0] and vr.SCENE_WARMUP_S > vr.WARMUP_S


def test_rows_of_scenes_and_configs_not_measured_stay(tmp_path, gl):
    """A run keeps the rows of the scenes and configs it does not measure from the folder's earlier
    run (same device, size, poses and seed), so they can run as separate commands; another seed
    starts afresh."""
    from rayvr.bench import vr

    kw = dict(size=(16, 12), scenes=("default",), poses=1, cameras=("pinhole",), counts=(1,), repeat=1, warmup=1,
              progress=False, gl=gl)
    vr.run(tmp_path, configs=("shadows",), **kw)
    data = json.loads((tmp_path / "vr.json").read_text())
    data["rows"].append({**data["rows"][0], "scene": "sponza", "frame_ms": 123.0})
    data["meta"]["scenes"]["sponza"] = data["meta"]["scenes"]["default"]
    (tmp_path / "vr.json").write_text(json.dumps(data))
    kept = vr.run(tmp_path, configs=("room",), **kw)
    assert [(r["scene"], r["config"]) for r in kept["rows"]] == [("default", "shadows"), ("sponza", "shadows"),
                                                                  ("default", "room")]
    assert set(kept["meta"]["scenes"]["default"]["configs"]) == {"shadows", "room"}
    md = (tmp_path / "vr.md").read_text()
    assert "## sponza" in md and "| 123.000 |" in md and "| room | default | pinhole |" in md
    again = vr.run(tmp_path, configs=("room",), **kw)  # measured again: replaced, not doubled
    assert [(r["scene"], r["config"]) for r in again["rows"]] == [("default", "shadows"), ("sponza", "shadows"),
                                                                   ("default", "room")]
    fresh = vr.run(tmp_path, configs=("room",), pose_seed=5, **kw)
    assert [(r["scene"], r["config"]) for r in fresh["rows"]] == [("default", "room")]


def test_a_missing_scene_is_skipped_with_its_reason(tmp_path, gl, monkeypatch):
    from rayvr.bench import scenes, vr

    monkeypatch.setattr(scenes, "SHARED_SCENES", tmp_path / "no_scenes")
    result = vr.run(tmp_path, size=(16, 12), scenes=("sponza",), poses=1, cameras=("pinhole",), counts=(1,),
                    configs=("shadows",), repeat=1, warmup=1, progress=False, gl=gl)
    assert result["rows"] == [] and "not found" in result["meta"]["skipped"]["sponza"]
    assert "**skipped** sponza:" in (tmp_path / "vr.md").read_text()


@pytest.mark.parametrize("args, message", [
    (("--configs", "glossy"), "bench vr --configs must be among shadows, ssr, room, budget, got glossy"),
    (("--counts", "3"), "sub-ray counts must be among 1, 4, 8, 16, 32, got '3'"),
    (("--poses", "0"), "bench vr --poses must be at least 1, got 0"),
    (("--cameras", "pinhole,fisheye"), "bench vr --cameras must be among raster_gbuffer, pinhole"),
])
def test_bad_input_is_one_line(tmp_path, args, message):
    run = run_rayvr("bench", "vr", "--quick", "--out", tmp_path, *args)
    assert run.returncode == 2
    assert message in run.stderr and len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert not (tmp_path / "vr.json").exists()


def test_a_variant_may_not_set_what_the_grid_sets(tmp_path):
    from rayvr.bench import vr

    with pytest.raises(ValueError, match="variant 'x' sets msaa, which the grid sets per row"):
        vr.run(tmp_path, variants={"x": {"msaa": 4}})
    with pytest.raises(ValueError, match="variant .x.: unknown render option.s. no_such_option"):
        vr.run(tmp_path, variants={"x": {"no_such_option": 1}})
    assert not (tmp_path / "vr.json").exists()


def _choice_row(variant, fields, model, msaa, pose, ms, **plan):
    return {"primary": "rays", "variant": variant, "variant_fields": fields, "camera_model": model, "msaa": msaa,
            "scene": "sponza", "config": "shadows", "pose": {"index": pose}, "camera": model, "frame_ms": ms,
            **{"tile_culling": True, "tile_lists": 0, "block_culling": False, **plan}}


def test_the_fastest_variant_is_chosen_on_its_worst_pose_among_primary_knobs_only():
    from rayvr.bench.vr import primary_choices

    rows = [_choice_row("entries", {}, "pinhole", 16, 0, 10.0), _choice_row("entries", {}, "pinhole", 16, 1, 14.0),
            _choice_row("lists", {"tile_lists": 256}, "pinhole", 16, 0, 12.0, tile_lists=256),
            _choice_row("lists", {"tile_lists": 256}, "pinhole", 16, 1, 12.5, tile_lists=256),
            # not a primary-visibility knob: never a choice, however fast
            _choice_row("cheap", {"ray_order": "morton"}, "pinhole", 16, 0, 1.0),
            _choice_row("cheap", {"ray_order": "morton"}, "pinhole", 16, 1, 1.0),
            # measured on pose 0 only: judged on the cells every variant has
            _choice_row("entries", {}, "dof", 4, 0, 5.0, tile_culling=False),
            _choice_row("blocks", {"block_culling": True}, "dof", 4, 0, 4.0, block_culling=True),
            _choice_row("blocks", {"block_culling": True}, "dof", 4, 1, 99.0, block_culling=True)]
    # a win inside the noise margin (CHOICE_MARGIN) leaves the variant the run listed first
    rows = [_choice_row("perray", {"tile_culling": False}, "foveated", 16, 0, 9.25, tile_culling=False),
             _choice_row("blocks", {"block_culling": True}, "foveated", 16, 0, 9.08, block_culling=True),
             _choice_row("perray", {"tile_culling": False}, "wide", 16, 0, 9.40, tile_culling=False),
             _choice_row("blocks", {"block_culling": True}, "wide", 16, 0, 9.08, block_culling=True)] + rows
    chosen = primary_choices(rows)
    assert chosen["foveated"][16]["variant"] == "perray" and chosen["wide"][16]["variant"] == "blocks"
    assert chosen["pinhole"][16]["variant"] == "lists"   # 12.5 worst against 14.0
    # the shapes a row does not name (runs from before they were knobs) are the ones those runs used
    assert chosen["pinhole"][16]["knobs"] == {"tile_culling": True, "tile_lists": 256, "block_culling": False,
                                              "tile_size": "16x8", "tile_entries": 32, "block_tiles": 8}
    assert chosen["pinhole"][16]["worst_ms"] == {"entries": 14.0, "lists": 12.5}
    assert chosen["dof"][4]["variant"] == "blocks" and chosen["dof"][4]["worst_ms"]["blocks"] == 4.0


def test_a_choice_is_judged_by_the_primary_pass_not_the_frame():
    """The knobs change only the primary_rays pass: a variant whose frame was faster by another pass's
    noise but whose primary pass was slower is not chosen."""
    from rayvr.bench.vr import primary_choices

    rows = [{**_choice_row("chosen", {}, "wide", 4, 0, 8.3), "passes": {"primary_rays": 2.80, "shade": 3.0}},
            {**_choice_row("t8", {"tile_size": "8x8"}, "wide", 4, 0, 8.1, tile_size="8x8"),
             "passes": {"primary_rays": 2.95, "shade": 2.6}}]
    chosen = primary_choices(rows)["wide"][4]
    assert chosen["variant"] == "chosen" and chosen["worst_ms"] == {"chosen": 2.80, "t8": 2.95}


def test_the_renderer_takes_the_measured_choices(tmp_path, monkeypatch, gl):
    """A choices file (what bench vr writes from its variants) sets the knobs the settings leave to
    the renderer; explicit settings still win; a file breaking the knobs' rules is refused."""
    from rayvr.bench.vr import choices_file, primary_choices
    from rayvr.frame.passes import primary_rays

    rows = [_choice_row("lists", {"tile_lists": 64, "block_culling": True}, "pinhole", 16, 0, 3.0, tile_lists=64,
                        block_culling=True),
            _choice_row("small", {"tile_size": "8x8", "block_culling": True, "block_tiles": 4}, "pinhole", 4, 0, 1.0,
                        block_culling=True, tile_size="8x8", tile_entries=16, block_tiles=4)]
    meta = {"date": "today", "poses": 1, "pose_seed": 22, "per_eye_size": [8, 8], "gl_renderer": "GPU",
            "gl_version": "4.3"}
    data = choices_file(primary_choices(rows), meta, tmp_path)
    assert data["choices"]["foveated"] == json.loads(primary_rays.MEASURED_CHOICES.read_text())["choices"]["foveated"]
    del data["choices"]["pinhole"]["32"]   # a count not measured: the one below it rules
    path = tmp_path / "primary_visibility.json"
    path.write_text(json.dumps(data))
    monkeypatch.setattr(primary_rays, "MEASURED_CHOICES", path)
    try:
        with Renderer(None, gl=gl) as r:
            r.settings = RenderSettings(msaa=16)
            plan = r.plan()
            assert plan.tile_culling and plan.tile_lists == 64 and plan.block_culling
            r.settings = RenderSettings(msaa=32)   # the largest count measured at or below
            assert r.plan().tile_lists == 64
            r.settings = RenderSettings(msaa=16, tile_lists=0, block_culling=False)
            assert r.plan().tile_lists == 0 and not r.plan().block_culling
            r.settings = RenderSettings(msaa=4)   # the shapes the run's plan had
            plan = r.plan()
            assert (plan.tile_pixels, plan.tile_entries, plan.block_tiles) == ((8, 8), 16, 4)
            r.settings = RenderSettings(msaa=4, tile_size="16x16", block_tiles=8)
            plan = r.plan()
            assert (plan.tile_pixels, plan.tile_entries, plan.block_tiles) == ((16, 16), 16, 8)
        data["choices"]["pinhole"]["4"] = {"tile_culling": False, "tile_lists": 64, "block_culling": False}
        path = tmp_path / "broken.json"
        path.write_text(json.dumps(data))
        with pytest.raises(ValueError, match="only with tile culling"):
            primary_rays.measured_choices(path)
    finally:
        primary_rays._read_choices.cache_clear()


def test_the_shipped_choices_cover_every_built_in_model_and_count():
    from rayvr.frame.cameras import CAMERA_MODELS
    from rayvr.frame.cameras.sampling import SAMPLE_COUNTS
    from rayvr.frame.passes.primary_rays import measured_choices

    table = measured_choices()
    assert set(table) == set(CAMERA_MODELS) and all(set(c) == set(SAMPLE_COUNTS) for c in table.values())
    for model, counts in table.items():   # where a model declines culling, its measured choice does too
        assert all(not k["tile_culling"] for k in counts.values()) or CAMERA_MODELS[model].culls_tiles_by_default


def test_rows_count_each_effects_rays_on_the_gpu(quick):
    """Every row's `rays` holds each traced effect of its config, counted on the GPU: `shadows` traces
    shadow rays alone; the room's glossy and mirror materials trace closest hits exactly where the
    frame shows them; vr.md prints them per pixel of the effect."""
    result, md = quick
    for r in result["rows"]:
        rays = r["rays"]
        assert "shadows" in rays and rays["shadows"]["closest"] == 0 and rays["shadows"]["shadow"] > 0, r
        w, h = result["meta"]["per_eye_size"]
        for n in rays.values():
            assert n["shadow_per_pixel"] == pytest.approx(n["shadow"] / (2 * w * h))
        if r["config"] == "room":  # a reflective effect in view traces closest hits; out of view, none
            for effect in ("glossy", "reflections"):
                assert (rays[effect]["closest"] > 0) == (r["effect_share"].get(effect, 0.0) > 0), (effect, r)
    assert any(r["rays"].get("glossy", {}).get("closest") for r in result["rows"])
    assert "rays a pixel of it" in md
