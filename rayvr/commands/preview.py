"""`rayvr preview`: the desktop stereo preview window (glfw)."""
from __future__ import annotations

from . import args as shared

COMMAND = "preview"


def add_parser(sub) -> None:
    from ..gl.gpu_layout import VIEWS

    v = sub.add_parser("preview", help="desktop stereo preview window (glfw); H in the window lists the keys")
    v.add_argument("scene", nargs="?", help="glTF/GLB, OBJ or PLY file (default: built-in room)")
    v.add_argument("--materials", help="material-ID config (TOML), reloaded when the file changes; its [render] "
                   "table sets render options at start (the flags override it)")
    v.add_argument("--size", type=shared.size, default=(1280, 720), help="window size WxH (default 1280x720)")
    v.add_argument("--mode", choices=("side-by-side", "cross-eyed", "anaglyph", "left", "right"),
                   default="side-by-side", help="stereo mode at start (Tab cycles)")
    v.add_argument("--view", choices=VIEWS, default="color", help="colour or a debug view at start (V cycles)")
    v.add_argument("--scale", type=float, help="resolution scale (default 1, 0.5 on a CPU rasterizer)")
    v.add_argument("--no-vsync", action="store_true", help="start with vsync off (Y toggles)")
    shared.add_pose_arguments(v.add_argument_group("camera / stereo rig at start"))
    v.add_argument("--out", default="shots", help="screenshot folder (default ./shots)")
    v.add_argument("--record", default="camera_path.json", help="camera path file P writes")
    v.add_argument("--frames", type=shared.FRAMES, help="close after N frames (smoke tests)")
    shared.add_budget_arguments(v, "pick effects per material to fit this GPU frame time at start",
                                frame_knobs=False)
    shared.add_render_arguments(v, COMMAND)  # --stereo: the second eye at start (B cycles); --denoise (N), ...
    v.set_defaults(func=cmd_preview)


def start_config(path):
    """The config the window starts from, for its [render] table; a bad file is the window's to
    show (in its HUD, as every later edit of it), so it starts without the table."""
    from ..scene.materials import ConfigError, load_config

    try:
        return load_config(path)
    except ConfigError:
        return None


def preview_settings(args):
    """(RenderSettings, the options given) of the flags over the config's [render] table."""
    from ..renderer import RenderSettings

    given = shared.render_values(args, COMMAND, start_config(args.materials))
    return RenderSettings(**given), given


def cmd_preview(args) -> int:
    from ..app.preview import Preview

    settings, given = preview_settings(args)
    shared.budget_grid(args, given, ())  # --budget-hz: the budget in ms
    rig_options = shared.rig_keywords(args, shared.camera_from_args(args, settings, given))
    look_at = (args.pose[:3], args.pose[3:]) if args.pose else None
    with Preview(args.scene, args.materials, size=args.size, vsync=not args.no_vsync, stereo=args.mode,
                 stereo_method=settings.stereo, view=args.view, res_scale=args.scale, rig_options=rig_options,
                 look_at=look_at, out_dir=args.out, path_file=args.record, seed=settings.seed,
                 settings=settings) as p:
        if args.budget_ms is not None:
            print(p.apply_budget(args.budget_ms))
        p.run(max_frames=args.frames)
    return 0
