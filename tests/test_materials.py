import logging

import pytest

from rayvr.frame.effects import EFFECTS, PLANNED
from rayvr.scene.materials import ConfigError, load_config, parse_config

NAMES = ["floor", "mirror_ball", "mirror_panel", "walls", "gold"]


def write(tmp_path, text):
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def test_default_is_all_raster():
    cfg = load_config(None)
    assert [a.effect for a in cfg.assign(NAMES)] == ["raster"] * len(NAMES)


def test_exact_id_glob_precedence():
    cfg = parse_config({
        "default": "raster",
        "params": {"shadows": {"area_samples": 8}},
        "materials": {"mirror*": {"effect": "shadows", "area_samples": 2}, "mirror_panel": "raster"},
        "ids": {"0": "shadows"},
    }, "t.toml")
    got = cfg.assign(NAMES)
    assert got[0].effect == "shadows" and got[0].params["area_samples"] == 8 and got[0].rule == "ids.0"
    assert got[1].effect == "shadows" and got[1].params["area_samples"] == 2 and got[1].rule == "materials.mirror*"
    assert got[2].effect == "raster" and got[2].rule == "materials.mirror_panel"  # exact beats glob
    assert got[3].rule == "default"
    assert got[0].effect_id == EFFECTS["shadows"].id


@pytest.mark.parametrize("text, words", [
    ('default = "sparkles"', ["m.toml", "default", "sparkles", "raster", "photon"]),
    ('[materials]\nfloor = 3', ["materials.floor", "expected an effect name"]),
    ('[materials]\nfloor = { bounces = 2 }', ["materials.floor", "'effect'"]),
    ('[materials]\nfloor = { effect = "raster", bounces = 2 }', ["materials.floor.bounces", "allowed: none"]),
    ('colour = "red"', ["colour", "unknown top-level key", "materials"]),
    ('[ids]\nabc = "raster"', ["ids.abc", "integers"]),
    ('default = 1', ["default", "must be a string"]),
    ('[params.raster]\nsamples = 2', ["params.raster.samples", "unknown parameter"]),
    ('[params.warp]\nx = 1', ["params.warp", "unknown effect"]),
    ('default = [', ["not valid TOML"]),
])
def test_validation_errors_name_file_key_and_allowed(tmp_path, text, words):
    with pytest.raises(ConfigError) as e:
        load_config(write(tmp_path, text))
    for w in words:
        assert w in str(e.value), (w, str(e.value))


def test_unimplemented_effect_fails_loudly_at_load(tmp_path, monkeypatch):
    unimplemented = [name for name in PLANNED if name not in EFFECTS]
    assert unimplemented == [], unimplemented  # every rung is implemented now: try a planned one
    monkeypatch.setitem(PLANNED, "future", "a rung not written yet")
    unimplemented = ["future"]
    for name in unimplemented:
        with pytest.raises(ConfigError, match="not implemented yet"):
            load_config(write(tmp_path, f'[materials]\nfloor = "{name}"'))


def test_wrong_parameter_type_and_range(tmp_path):
    with pytest.raises(ConfigError, match=r"materials.floor.bounces: expected int, got str"):
        load_config(write(tmp_path, '[materials]\nfloor = { effect = "reflections", bounces = "two" }'))
    with pytest.raises(ConfigError, match=r"materials.floor.bounces: 99 is outside the allowed range \[1, 16\]"):
        load_config(write(tmp_path, '[materials]\nfloor = { effect = "reflections", bounces = 99 }'))
    with pytest.raises(ConfigError, match="expected int, got bool"):
        load_config(write(tmp_path, '[materials]\nfloor = { effect = "reflections", bounces = true }'))


def test_unknown_material_warns_with_scene_names(tmp_path, caplog):
    cfg = load_config(write(tmp_path, '[materials]\n"flor" = "raster"\n"nothing*" = "raster"\n[ids]\n42 = "raster"'))
    with caplog.at_level(logging.WARNING):
        cfg.assign(NAMES)
    msg = caplog.text
    assert "materials.flor" in msg and "materials.nothing*" in msg and "ids.42" in msg
    assert "floor, mirror_ball, mirror_panel, walls, gold" in msg
    assert "ids.42 match no material" in msg and "(did you mean floor?)" in msg  # the typo's near name
    assert set(cfg.unmatched(NAMES)) == {"flor", "nothing*", "42"}
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        load_config(write(tmp_path, '[materials]\n"flor" = "raster"')).assign(NAMES)
    assert "materials.flor matches no material" in caplog.text  # one key: singular


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read material config"):
        load_config(tmp_path / "absent.toml")


def test_shipped_example_configs_are_valid():
    from pathlib import Path
    import rayvr
    examples = sorted((Path(rayvr.__file__).parent / "assets").glob("*.toml"))
    assert examples, "no example configs shipped in rayvr/assets"
    for p in examples:
        load_config(p)  # every shipped example uses implemented effects only


def test_importance_weights(tmp_path):
    cfg = load_config(write(tmp_path, '[materials]\n"floor" = { effect = "raster", importance = 3 }\n'
                                      '"mirror*" = { effect = "raster", importance = 0.5 }\n'))
    got = cfg.assign(NAMES, warn=False)
    assert [a.importance for a in got] == [3.0, 0.5, 0.5, 1.0, 1.0]
    with pytest.raises(ConfigError, match=r"materials.floor.importance: expected a number >= 0"):
        load_config(write(tmp_path, '[materials]\n"floor" = { effect = "raster", importance = -1 }\n'))


GLOB_TOML = '''
default = "shadows"
[materials]
"mirror_*"    = "reflections"
"*_panel"     = { effect = "glossy", samples = 2 }
"mirror*"     = { effect = "shadows", area_samples = 3 }
"Mirror*"     = { effect = "glossy", samples = 5 }
"*"           = "raster"
"mirror_ball" = { effect = "glossy", samples = 7 }
'''


def test_globs_match_case_sensitively_and_the_first_in_file_order_wins(tmp_path):
    """Several overlapping globs: a name takes the first glob of the file that matches it, with
    case, unless it is named exactly. Expected rules worked out by hand from the globs above."""
    cfg = load_config(write(tmp_path, GLOB_TOML))
    want = {
        "mirror_panel": "mirror_*",      # mirror_*, *_panel, mirror*, * match: the first
        "floor_panel": "*_panel",        # *_panel, *
        "mirrorball": "mirror*",         # mirror*, *
        "Mirror_Ball": "Mirror*",        # not mirror_* / mirror*: case counts
        "MIRROR_PANEL": "*",             # none of mirror_*, *_panel, mirror*, Mirror* with case
        "mirror_ball": "mirror_ball",    # the exact name beats every glob, wherever it stands
        "floor": "*",
    }
    got = {n: a for n, a in zip(want, cfg.assign(list(want), warn=False))}
    assert {n: a.rule for n, a in got.items()} == {n: f"materials.{r}" for n, r in want.items()}
    assert got["mirror_panel"].effect == "reflections"
    assert got["floor_panel"].effect == "glossy" and got["floor_panel"].params["samples"] == 2
    assert got["mirrorball"].effect == "shadows" and got["mirrorball"].params["area_samples"] == 3
    assert got["Mirror_Ball"].effect == "glossy" and got["Mirror_Ball"].params["samples"] == 5
    assert got["MIRROR_PANEL"].effect == "raster" and got["mirror_ball"].params["samples"] == 7


def test_glob_order_is_the_files_not_the_specificity(tmp_path):
    """The same two globs in both orders: whichever comes first wins, however specific the other."""
    for first, second in (("mirror*", "mirror_p*"), ("mirror_p*", "mirror*")):
        cfg = load_config(write(tmp_path, f'[materials]\n"{first}" = "shadows"\n"{second}" = "reflections"\n'))
        (a,) = cfg.assign(["mirror_panel"], warn=False)
        assert a.rule == f"materials.{first}" and a.effect == "shadows"


def test_globs_of_another_case_match_nothing(tmp_path, caplog):
    cfg = load_config(write(tmp_path, '[materials]\n"FLOOR*" = "shadows"\n"Mirror_?all" = "reflections"\n'))
    with caplog.at_level(logging.WARNING):
        got = cfg.assign(NAMES)
    assert [a.rule for a in got] == ["default"] * len(NAMES)
    assert "materials.FLOOR*" in caplog.text and "materials.Mirror_?all" in caplog.text
    assert set(cfg.unmatched(NAMES)) == {"FLOOR*", "Mirror_?all"}
    assert cfg.unmatched(["FLOORS", "Mirror_ball"]) == []
