"""quality/rungs.py: the per-material settings a budget pick may take (`--rung-params`): their
keys, their one-line refusals, and the config a pick of them becomes."""
import pytest

from conftest import run_rayvr
from rayvr.frame.effects import implemented_effects
from rayvr.quality.measure import config_for_assignment
from rayvr.quality.rungs import budget_rungs, parse_rung, parse_rung_params
from rayvr.scene.materials import load_config


class Scene:
    def material_names(self):
        return ["floor", "gold", "wall"]


def test_settings_become_rung_keys_and_back():
    keys = parse_rung_params("glossy.samples=1,4; path.samples=4 ;photon.radius=0.05")
    assert keys == ["glossy(samples=1)", "glossy(samples=4)", "path(samples=4)", "photon(radius=0.05)"]
    assert parse_rung("glossy(samples=4)") == ("glossy", {"samples": 4})
    assert parse_rung("photon(radius=0.05)") == ("photon", {"radius": 0.05})
    assert parse_rung("shadows") == ("shadows", {})
    assert parse_rung_params(None) == parse_rung_params("") == [] and budget_rungs(None) is None
    assert budget_rungs("path.samples=4") == list(implemented_effects()) + ["path(samples=4)"]


@pytest.mark.parametrize("text, says", [
    ("glossy.samples", "is not EFFECT.PARAM=VALUE"), ("mirror.samples=1", "'mirror' is not an effect"),
    ("glossy.nope=1", "glossy has no parameter 'nope'; it has samples"),
    ("ssr.gamma_norm=1", "one value for the whole frame"), ("glossy.samples=x", "is not an integer"),
    ("glossy.samples=-3", "is outside"), ("glossy.samples=", "no values")])
def test_bad_settings_are_one_line(text, says):
    with pytest.raises(ValueError, match=says):
        parse_rung_params(text)


def test_a_picked_setting_is_the_material_config_it_names():
    """The rung's setting lands on its material, over the base config's parameters of that
    effect (default_room.toml: floor glossy with 4 samples, gold glossy with 8); a plain rung keeps
    the base's parameters; an unnamed material is raster."""
    base = load_config("rayvr/assets/default_room.toml")
    got = config_for_assignment(base, Scene(), {"floor": "glossy(samples=16)", "gold": "glossy",
                                                "wall": "path(bounces=2)"})
    floor, gold, wall = got.assign(Scene().material_names(), warn=False)
    hits = {"hit_area_samples": 0}  # (glossy's default: the pixel's area_samples spread over its rays)
    assert (floor.effect, floor.params) == ("glossy", {"samples": 16, "bounces": 1, "area_samples": 4, **hits})
    assert (gold.effect, gold.params) == ("glossy", {"samples": 8, "bounces": 1, "area_samples": 4, **hits})
    assert wall.effect == "path" and wall.params == {**base.effect_params("path"), "bounces": 2}
    assert config_for_assignment(base, Scene(), {}).assign(["wall"], warn=False)[0].effect == "raster"


def test_the_bench_refuses_a_bad_setting_in_one_line(tmp_path):
    run = run_rayvr("bench", "budget", "--quick", "--rung-params", "glossy.nope=1", "--out", tmp_path / "o",
                    timeout=120)
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    assert run.stderr.strip().splitlines()[-1].endswith("rung params: glossy has no parameter 'nope'; it has "
                                                         "samples, bounces, area_samples, hit_area_samples")
    assert not (tmp_path / "o").exists()
