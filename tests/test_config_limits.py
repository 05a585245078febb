"""Material configs cannot make rayvr print megabytes or crash: what a message echoes is capped,
absurd nesting and oversized files are refused with one ConfigError naming the file."""
import pytest

from conftest import run_rayvr
from rayvr.scene.materials import ECHO_LIMIT, MAX_CONFIG_BYTES, ConfigError, load_config, parse_config, short

HUGE = "x" * 10_000_000  # 10 MB


def message(fn, *args) -> str:
    with pytest.raises(ConfigError) as info:
        fn(*args)
    return str(info.value)


def test_short_caps_with_an_ellipsis():
    assert short("floor") == "floor"
    assert short("a" * ECHO_LIMIT) == "a" * ECHO_LIMIT
    cut = short("a" * (ECHO_LIMIT + 1))
    assert len(cut) == ECHO_LIMIT and cut.endswith("\u2026")


@pytest.mark.parametrize("doc, words", [
    ({"materials": {"floor": HUGE}}, "materials.floor: unknown effect 'xxx"),         # a value
    ({"materials": {HUGE: "sparkle"}}, "materials.xxx"),                                # a key
    ({"materials": {"floor": {"effect": HUGE}}}, "materials.floor.effect: unknown effect"),
    ({"materials": {"floor": {"effect": "shadows", HUGE: 1}}}, "unknown parameter"),
    ({"materials": {"floor": {"effect": "shadows", "area_samples": HUGE}}}, "expected int, got str"),
    ({"materials": {"floor": {"effect": "shadows", "importance": HUGE}}}, "importance: expected a number"),
    ({"materials": {"floor": [HUGE]}}, "expected an effect name or a table"),
    ({"default": [HUGE] * 3}, "default: effect must be a string, got list"),
    ({HUGE: 1}, "unknown top-level key"),
    ({"params": {HUGE: {}}}, "params.xxx"),
    ({"ids": {HUGE: "raster"}}, "keys must be non-negative integers"),
])
def test_messages_echo_at_most_a_capped_key_or_value(doc, words):
    text = message(parse_config, doc, "big.toml")
    assert words in text, text[:300]
    assert len(text) < 600, len(text)  # file, key path, the capped echo and the allowed values


def test_a_big_value_in_a_file_is_not_echoed_whole(tmp_path):
    p = tmp_path / "big.toml"
    p.write_text(f'[materials]\nfloor = "{"y" * (MAX_CONFIG_BYTES // 2)}"\n')
    text = message(load_config, p)
    assert str(p) in text and "materials.floor: unknown effect 'yyy" in text and len(text) < 600


def test_absurd_nesting_is_refused_cleanly(tmp_path):
    p = tmp_path / "deep.toml"
    depth = 100_000
    p.write_text("x = " + "[" * depth + "]" * depth + "\n")
    assert p.stat().st_size < MAX_CONFIG_BYTES  # refused for its nesting, not its size
    text = message(load_config, p)
    assert text == f"{p}: material config nested too deeply (arrays or tables hundreds of levels inside each other)"


def test_files_over_the_size_limit_are_refused_before_parsing(tmp_path):
    p = tmp_path / "huge.toml"
    p.write_text('default = "raster"\n' + "#" * MAX_CONFIG_BYTES + "\n")  # valid TOML, too big
    assert message(load_config, p).startswith(f"{p}: material config is larger than 1 MiB")
    ok = tmp_path / "ok.toml"
    ok.write_text('default = "shadows"\n' + "#" * (MAX_CONFIG_BYTES - 100) + "\n")
    assert load_config(ok).default == "shadows"


def test_text_that_is_not_utf8_is_a_config_error(tmp_path):
    p = tmp_path / "latin1.toml"
    p.write_bytes(b'[materials]\n"caf\xe9" = "raster"\n')
    assert "not UTF-8" in message(load_config, p)


def test_cli_shows_one_short_line_for_a_huge_config_value(tmp_path):

    p = tmp_path / "big.toml"
    p.write_text(f'[materials]\nfloor = "{"z" * (MAX_CONFIG_BYTES // 2)}"\n')
    run = run_rayvr("capture", "--materials", p, "--out", tmp_path / "o", "--size", "8x8")
    assert run.returncode == 2 and len(run.stderr.splitlines()) == 1 and len(run.stderr) < 700, run.stderr[:300]
