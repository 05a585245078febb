"""Render options declared by their owners (rayvr/options.py): one declaration gives the
RenderSettings field and its validation, the CLI flag of each command that offers it, the
`[render]` key of a materials TOML, the `rayvr options` entry and the job file's record; plan
options reach the FramePlan (the compiled graphs' key), the others never do."""
import dataclasses
import json
import re
import warnings

import pytest

from conftest import run_rayvr
from rayvr import options, settings as settings_mod
from rayvr.cli import build_parser, main
from rayvr.frame.cameras import Distorted
from rayvr.frame.graph import FramePlan
from rayvr.scene.materials import ConfigError, MaterialConfig, load_config, parse_config
from rayvr.renderer import Renderer, RenderSettings


def parse(*argv):
    return build_parser().parse_args(list(argv))


def cli_error(capsys, *argv) -> str:
    """The one line argparse refuses `argv` with."""
    with pytest.raises(SystemExit) as exc:
        parse(*argv)
    assert exc.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def settings_error(**kw) -> str:
    with pytest.raises(ValueError) as exc:
        RenderSettings(**kw)
    return str(exc.value)


def toml_error(tmp_path, body: str) -> str:
    p = tmp_path / "cfg.toml"
    p.write_text(body)
    with pytest.raises(ConfigError) as exc:
        load_config(p)
    return str(exc.value)


def test_a_real_option_is_a_field_a_flag_of_each_command_a_toml_key_and_a_listing_entry(tmp_path, capsys):
    option = settings_mod.all_options()["quadtree_adapt"]  # declared by render_options/quadtree.py
    assert option.owner == "rayvr.render_options.quadtree" and set(option.commands) == {"capture", "preview"}
    assert RenderSettings().quadtree_adapt == 0.0 and RenderSettings(quadtree_adapt=2).quadtree_adapt == 2.0
    for command in ("capture", "preview"):
        assert parse(command, "--quadtree-adapt", "0.5").quadtree_adapt == 0.5
        assert parse(command).quadtree_adapt is None  # unset: the config's or the default
    assert "--quadtree-adapt" in cli_error(capsys, "info", "--quadtree-adapt", "1")  # info does not offer it
    (tmp_path / "cfg.toml").write_text("[render]\nquadtree_adapt = 3\n")
    assert load_config(tmp_path / "cfg.toml").render == {"quadtree_adapt": 3.0}
    assert main(["options", "quadtree_adapt"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("quadtree_adapt  --quadtree-adapt\n") and "[0, 1e+06]" in out and "scope frame" in out
    assert "declared in rayvr.render_options.quadtree" in out and "Widmer" in out


def test_every_module_that_declares_an_option_is_an_owner():
    """RenderSettings' fields are the options of settings.OWNERS: a declaration elsewhere in rayvr
    would be left out of them."""
    import re
    from pathlib import Path

    root = Path(settings_mod.__file__).parent
    declaring = {".".join(("rayvr",) + p.relative_to(root).with_suffix("").parts)
                 for p in root.rglob("*.py") if re.search(r"^\w+ = declare(_option)?\(Option\(", p.read_text(), re.M)}
    assert declaring == set(settings_mod.RANK)
    assert {o.owner for o in settings_mod.all_options().values()} == declaring


def test_a_toy_option_declared_from_a_test_appears_everywhere_then_goes(tmp_path, capsys):
    toy = options.declare(options.Option("toy_glow", float, 0.25, "glow of the toy pass", bounds=(0, 1),
                                         commands=("capture", "bench")), owner="tests.toy")
    try:
        assert parse("capture", "--toy-glow", "0.5").toy_glow == 0.5
        assert parse("bench", "rays", "--toy-glow", "1").toy_glow == 1.0
        line = cli_error(capsys, "capture", "--toy-glow", "2")
        assert line == "rayvr capture: error: argument --toy-glow: toy_glow must be in [0, 1], got 2.0 " \
                       "(see rayvr capture -h)"
        assert toy.check(0.75) == 0.75
        from rayvr.commands.args import settings_from_args

        settings = settings_from_args(parse("capture", "--toy-glow", "0.5"), "capture")  # into RenderSettings.more
        assert settings.toy_glow == 0.5 and RenderSettings().toy_glow == 0.25 and settings.to_dict()["toy_glow"] == 0.5
        assert RenderSettings.from_dict(settings.to_dict()) == settings
        assert parse_config({"render": {"toy_glow": 0.5}}).render == {"toy_glow": 0.5}
        assert toml_error(tmp_path, "[render]\ntoy_glow = -1\n").endswith("render.toy_glow must be in [0, 1], got -1")
        assert main(["options"]) == 0
        listing = capsys.readouterr().out
        assert "toy_glow  --toy-glow\n    float, default 0.25, [0, 1]; scope frame; commands: capture, bench; " \
               "declared in tests.toy\n    glow of the toy pass\n" in listing
        assert listing.index("ssaa  --ssaa") < listing.index("toy_glow")  # after the owners' options
    finally:
        options.remove("toy_glow")
    assert "unrecognized arguments: --toy-glow" in cli_error(capsys, "capture", "--toy-glow", "0.5")
    assert "toy_glow" not in settings_mod.all_options()
    assert "unknown render option" in toml_error(tmp_path, "[render]\ntoy_glow = 0.5\n")


@pytest.mark.parametrize("name, text, value", [
    ("exposure", "1e38", 1e38), ("exposure", "0", 0.0), ("exposure", "nan", float("nan")),
    ("denoise_iterations", "9", 9), ("seed", "4294967296", 2**32), ("dof_samples", "0", 0),
    ("dof_diameter", "-2", -2.0), ("dof_focus", "0", 0.0), ("quadtree_adapt", "-1", -1.0),
    ("tonemapper", "filmic", "filmic"), ("msaa", "3", 3), ("warp_layers", "3", 3), ("stereo", "mono", "mono"),
    ("bvh_build", "kd", "kd"), ("traversal", "shadow=bvh3", "shadow=bvh3"),
    ("ray_order", "zigzag", "zigzag"), ("persistent", "yes", "yes")])
def test_a_bad_value_is_the_same_error_from_the_cli_the_toml_and_render_settings(tmp_path, capsys, name, text, value):
    said = settings_error(**{name: value})
    flag = settings_mod.all_options()[name].cli_flag
    line = cli_error(capsys, "capture", flag, text)
    assert line.startswith("rayvr capture: error: argument ") and line.endswith(f": {said} (see rayvr capture -h)")
    toml_value = json.dumps(value) if not (isinstance(value, float) and value != value) else "nan"
    from_toml = toml_error(tmp_path, f"[render]\n{name} = {toml_value}\n")
    assert from_toml.startswith(f"{tmp_path / 'cfg.toml'}: render.{name}") and from_toml.endswith(said)


def test_unknown_and_mistyped_render_keys_name_the_file_and_key(tmp_path):
    said = toml_error(tmp_path, "[render]\nexposur = 2\n")
    assert said.startswith(f"{tmp_path / 'cfg.toml'}: render.exposur: unknown render option; allowed: exposure, ")
    assert "msaa" in said and "dof_diameter" in said
    assert toml_error(tmp_path, "[render]\nssaa = 1\n").endswith("render.ssaa must be true or false, got 1")
    assert toml_error(tmp_path, "render = 3\n").endswith("render: expected a table of option = value entries")


def test_flags_override_the_config_render_table_and_imply_what_they_imply(tmp_path):
    from rayvr.commands.args import render_values

    cfg = parse_config({"render": {"exposure": 2.0, "tonemapper": "reinhard", "denoise_iterations": 2}})
    args = parse("capture", "--exposure", "3", "--temporal")
    values = render_values(args, "capture", cfg)
    assert values == {"exposure": 3.0, "tonemapper": "reinhard", "denoise_iterations": 2, "denoise": True,
                      "temporal": True, "accumulate": True}
    assert render_values(parse("capture", "--temporal"), "capture", parse_config(
        {"render": {"accumulate": False}}))["accumulate"] is False  # said outright: not implied over it


def test_render_settings_round_trip_through_a_capture_job_file_and_an_old_one_resumes(tmp_path):
    from rayvr.app.capture import identity_digest

    out = tmp_path / "o"
    flags = ["--exposure", "2.5", "--traversal", "bvh2", "--seed", "3", "--tonemapper", "clamp"]
    run = run_rayvr("capture", "--size", "8x6", "--frames", "2", "--out", out, "-q", *flags)
    assert run.returncode == 0, run.stderr
    job = json.loads((out / "frame_job.json").read_text())
    # (denoise: a capture's own default, commands/args.py CAPTURE_DEFAULTS)
    want = RenderSettings(exposure=2.5, traversal="bvh2", seed=3, tonemapper="clamp", denoise=True)
    assert job["settings"] == want.to_dict() and RenderSettings.from_dict(job["settings"]) == want
    # The folder as an older rayvr left it: the settings' repr in the job file, the records naming its digest.
    old = {**job, "settings": repr(want).replace("dof_diameter=", "dof_aperture=")}
    (out / "frame_job.json").write_text(json.dumps(old))
    for i in range(2):
        record = out / f"frame_{i:04d}_record.json"
        record.write_text(json.dumps({**json.loads(record.read_text()), "job": identity_digest(old)}))
    again = run_rayvr("capture", "--size", "8x6", "--frames", "2", "--out", out, *flags)
    assert again.returncode == 0 and "0 written, 2 skipped" in again.stdout, again.stdout + again.stderr
    other = run_rayvr("capture", "--size", "8x6", "--frames", "2", "--out", out, "-q", *flags[2:])
    assert other.returncode == 2 and "settings.exposure 2.5 -> 1.0" in other.stderr, other.stderr
    with pytest.raises(ValueError, match="unknown render option.*expo"):
        RenderSettings.from_dict({"expo": 1})


def test_preview_takes_the_render_options_it_lacked():
    from rayvr.commands.preview import preview_settings

    args = parse("preview", "--exposure", "2", "--traversal", "bvh8", "--second-layer", "peel",
                 "--quadtree-adapt", "0.5", "--tonemapper", "reinhard", "--denoise-iterations", "2",
                 "--warp-layers", "1", "--stereo", "warp", "--seed", "9")
    settings, given = preview_settings(args)
    assert settings == RenderSettings(exposure=2, traversal="bvh8", second_layer="peel", quadtree_adapt=0.5,
                                      tonemapper="reinhard", denoise=True, denoise_iterations=2, warp_layers=1,
                                      stereo="warp", seed=9)


def test_rayvr_options_lists_every_render_setting(capsys):
    assert main(["options", "--json"]) == 0
    entries = json.loads(capsys.readouterr().out)
    assert [e["name"] for e in entries] == [f.name for f in dataclasses.fields(RenderSettings) if f.name != "more"]
    by_name = {e["name"]: e for e in entries}
    assert by_name["exposure"]["allowed"] == "(0, 1e+06]" and by_name["exposure"]["owner"] == "rayvr.render_options.tonemap"
    assert by_name["msaa"]["plan_field"] == "subsamples" and by_name["msaa"]["flag"] == "--msaa"
    assert by_name["ambient"]["flag"] == "--ambient" and by_name["ambient"]["scope"] == "material"
    assert by_name["accumulate"]["flag"] is None  # an option no command offers as a flag
    assert main(["options", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rayvr options: error: unknown render option(s) nope; allowed: exposure, ")


def test_the_screen_space_lens_is_a_diameter_and_the_old_names_still_work(capsys):
    assert parse("capture", "--aperture", "0.2").dof_diameter == parse("capture", "--dof-diameter", "0.2").dof_diameter
    with pytest.warns(DeprecationWarning, match="dof_aperture is deprecated: use dof_diameter"):
        old = RenderSettings(dof_aperture=0.2)
    assert old == RenderSettings(dof_diameter=0.2) and old.dof_aperture == 0.2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert dataclasses.replace(old, dof_aperture=0.5).dof_diameter == 0.5
        assert settings_error(dof_aperture=-1.0) == "dof_aperture must be in [0, 1e+18], got -1.0"
    assert "dof_aperture" not in RenderSettings().to_dict()  # one name in files and listings
    with pytest.raises(SystemExit):
        parse("capture", "-h")
    help_ = " ".join(capsys.readouterr().out.split())  # argparse wraps the lines
    assert "--dof-diameter DOF_DIAMETER, --aperture DOF_DIAMETER" in help_
    assert "--aperture: deprecated spelling of --dof-diameter" in help_ and "aperture=RADIUS" in help_
    from rayvr.frame.cameras.thin_lens import ThinLens
    assert {f.name for f in dataclasses.fields(ThinLens)} >= {"aperture", "focus"}  # the model's own: a radius


# An allowed value other than the default, and what it needs to reach the plan at all.
OTHER = {"traversal": "bvh2", "layer_mode": "passes", "ambient": (0.1, 0.2, 0.3), "background": (0.3, 0.2, 0.1),
         "stereo": "reuse", "tile_lists": 64}
# The camera an option needs to reach the plan at all (the chromatic model's three channel sets).
CAMERA_CONTEXT = {"share_channel_shading": {"camera": Distorted()}}
CONTEXT = {"share_channel_shading": {"primary": "rays"}, "ssaa": {"msaa": 4}, "tile_culling": {"primary": "rays"},
           "tile_lists": {"primary": "rays"}, "block_culling": {"primary": "rays"}, "tile_size": {"primary": "rays"},
           "tile_entries": {"primary": "rays"}, "block_tiles": {"primary": "rays", "block_culling": True},
           "warp_layers": {"stereo": "warp"}}


def other_value(o: options.Option):
    if o.name in OTHER:
        return OTHER[o.name]
    if o.choices:
        return next(c for c in o.choices if c != o.default)
    if o.type is bool:
        return not o.default
    lo, hi = o.bounds
    return (lo + 1 if o.default == lo else lo) if o.type is int else (0.5 * o.default if o.default else min(hi, 0.5))


def test_plan_options_reach_their_plan_field_and_no_other_option_changes_the_plan(gl):
    """The FramePlan keys the compiled graphs: an option of scope "plan" must change its field
    (else a change would render with a stale graph), any other must leave the plan alone (else
    a uniform would recompile)."""
    config = MaterialConfig(default="shadows")  # a sampled effect: the denoiser has pixels to filter
    for o in settings_mod.all_options().values():
        context = CONTEXT.get(o.name, {})
        def plan(settings):
            with Renderer(None, config, gl=gl, settings=settings) as r:  # (the layer mode is picked here)
                return r.plan(eyes=2, **CAMERA_CONTEXT.get(o.name, {}))

        base = plan(RenderSettings(**context))
        # an automatic switch (None: the measured choice) set against what the renderer chose
        auto_switch = o.auto and o.type is bool and o.scope == "plan"
        value = (not getattr(base, o.plan_field)) if auto_switch else other_value(o)
        changed = plan(RenderSettings(**{**context, o.name: value}))
        if o.scope == "plan":
            assert o.plan_field in {f.name for f in dataclasses.fields(FramePlan)}
            assert getattr(changed, o.plan_field) != getattr(base, o.plan_field), o.name
        else:
            assert changed == base, o.name


def test_background_is_a_flag_by_its_declaration_alone(tmp_path):
    """The recipe (docs/options.md): `background` became a flag of capture and preview by adding
    `commands` to its declaration in frame/passes/shade.py; nothing else changed."""
    for command in ("capture", "preview"):
        assert parse(command, "--background", "1,0,0.5").background == (1.0, 0.0, 0.5)
    run = run_rayvr("capture", "--size", "16x12", "--camera", "0,1,3,0,1,-1000", "--far", "5",
                    "--background", "1,0,0", "--tonemapper", "clamp", "--out", tmp_path, "-q")
    assert run.returncode == 0, run.stderr
    import numpy as np
    from PIL import Image

    left = np.asarray(Image.open(tmp_path / "frame_left.png"))
    assert (left == (255, 0, 0)).all(-1).any()  # the far plane leaves background pixels, red
    bad = run_rayvr("capture", "--background", "1,0", "--out", tmp_path / "x")
    assert bad.returncode == 2 and bad.stderr.splitlines() == [
        "rayvr capture: error: argument --background: background must be 3 finite numbers R,G,B (linear), "
        "got (1.0, 0.0) (see rayvr capture -h)"]


@pytest.mark.parametrize("command", ["capture", "preview", "info", "bench", "options"])
def test_help_names_no_issue_and_no_device_run(command, capsys):
    """What a user reads speaks of the product, not of the lab (issue 44 item 4): no issue numbers,
    no GPU a run happened on (the measured choices name their runs in their own files)."""
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert not re.search(r"\b[Ii]ssues? #?\d+", text), re.search(r".{60}[Ii]ssues? #?\d+.{20}", text)
    assert not re.search(r"\bH[12]00\b", text), re.search(r".{60}H[12]00.{20}", text)
