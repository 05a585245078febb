"""`rayvr info`: the GL device, a scene's material effects, the compiled frame graph."""
from __future__ import annotations

import json

from . import args as shared

COMMAND = "info"


def add_parser(sub) -> None:
    from ..gl.gpu_layout import VIEWS

    i = sub.add_parser("info", help="GL vendor, renderer, version, limits, extensions; a scene's material effects")
    i.add_argument("scene", nargs="?", help="also list this scene's materials and their effects")
    i.add_argument("--materials", help="material-ID config to apply to the scene")
    i.add_argument("--backend", choices=("egl", "osmesa"))
    shared.add_device_argument(i)
    i.add_argument("--json", action="store_true")
    i.add_argument("--graph", nargs="?", const="text", choices=("text", "dot"),
                   help="print the compiled frame graph (passes in order, why each runs, resources); "
                        "'dot' for Graphviz")
    i.add_argument("--size", type=shared.size, default="1440x1600",
                   help="per-eye size the --graph resources are sized for")
    i.add_argument("--view", choices=VIEWS, default="color", help="the view --graph is compiled for")
    i.add_argument("--spp", type=shared.SPP, default=1, help="the --graph of a capture with this many samples a pixel")
    shared.add_render_arguments(i, COMMAND)
    shared.add_capture_default_arguments(i)
    i.set_defaults(func=cmd_info)


def print_graph(args) -> int:
    """`rayvr info SCENE --materials FILE --graph [dot]`: the compiled frame graph."""
    from ..gl.context import create_context
    from ..frame.graph import compile_graph
    from ..scene.defaults import materials_for
    from ..scene.materials import load_config
    from ..renderer import Renderer, RenderSettings, candidate_passes

    config = load_config(materials_for(args.scene, args.materials)[0])
    given = shared.render_values(args, COMMAND, config, **({"accumulate": True} if args.spp > 1 else {}))
    given = shared.with_capture_defaults(given)  # the graph a capture compiles
    settings = RenderSettings(**given)
    camera = shared.camera_from_args(args, settings, given)
    gl = create_context(args.backend)
    try:
        with Renderer(args.scene, config, gl=gl, settings=settings) as r:
            plan = r.plan(eyes=2, view=args.view, camera=camera)
            graph = compile_graph(candidate_passes(plan), plan)  # passes are not built: nothing compiles
            print(graph.dot() if args.graph == "dot" else graph.describe(r.sizing(args.size, plan.eyes, plan)), end="")
    finally:
        gl.release()
    if args.graph != "dot":
        print()
    return 0


def known(value) -> str:
    """A field the driver did not report is said to be unknown, not printed as None."""
    return "unknown" if value is None else str(value)


def egl_device_list() -> list[str]:
    """The EGL devices as --device numbers them ([] where EGL cannot enumerate them)."""
    from ..gl.context import ContextError, egl_devices

    try:
        return [d.describe() for d in egl_devices()]
    except ContextError:
        return []


def view_facts(scene) -> dict:
    """Where the scene is first seen from (app/viewpoint.py): its bounds, whether it encloses its
    centre, and the first view's pose in --pose syntax."""
    from ..app.viewpoint import SceneView, first_rig, first_view, pose_argument

    view = SceneView(scene)
    first = first_view(scene, view)
    met, facing = view.enclosed_shares
    return {"bounds": [list(map(float, b)) for b in scene.bounds], "rays_met": met, "rays_facing": facing,
            "encloses": view.encloses(), "first_view": first[0],
            "first_pose": pose_argument(first_rig(scene, (64, 64), first).pose)}


def cmd_info(args) -> int:
    from ..gl.context import create_context

    if args.graph:
        return print_graph(args)
    gl = create_context(args.backend)
    try:
        info = gl.info()
    finally:
        gl.release()
    info["egl_devices"] = egl_device_list()
    # the scene's materials and their effects: the built-in room's (with its own config) when none is named
    from ..scene import materials, loader as scene
    from ..scene.defaults import materials_for

    s = scene.load(args.scene)
    cfg = materials.load_config(materials_for(args.scene, args.materials)[0])
    assigned = cfg.assign(s.material_names(), warn=False)
    info["scene"] = {"summary": s.summary(), "materials": [
        {"index": i, "name": m.name, "effect": a.effect, "rule": a.rule, "params": a.params}
        for i, (m, a) in enumerate(zip(s.materials, assigned))],
        "lights": [{"kind": l.kind, "source": l.source} for l in s.lights],
        "unmatched_config_keys": cfg.unmatched(s.material_names()), **view_facts(s)}
    if args.json:
        print(json.dumps(info, indent=1, default=str))
        return 0
    print(f"backend   {info['backend']}")
    for key in ("vendor", "renderer", "version", "glsl"):
        print(f"{key:9s} {known(info[key])}")
    print("limits")
    for k, v in info["limits"].items():
        print(f"  {k:40s} {known(v)}")
    if info.get("egl_devices"):
        print("EGL devices (--device N)")
        for line in info["egl_devices"]:
            print(f"  {line}")
    print("extensions rayvr uses")
    for k, v in info["extensions"].items():
        print(f"  {'yes' if v else 'no ':3s} {k}")
    if "scene" in info:
        print(info["scene"]["summary"])
        v = info["scene"]
        lo, hi = (", ".join(f"{x:.4g}" for x in b) for b in v["bounds"])
        print(f"bounds    ({lo}) to ({hi}); encloses its centre: {'yes' if v['encloses'] else 'no'} "
              f"(of rays from it {v['rays_met']:.0%} meet a surface, {v['rays_facing']:.0%} one facing them)")
        print(f"first view {v['first_view']}: --pose {v['first_pose']}")
        for m in info["scene"]["materials"]:
            print(f"  [{m['index']:3d}] {m['name']:24s} -> {m['effect']:12s} ({m['rule']})")
        for key in info["scene"]["unmatched_config_keys"]:
            print(f"  warning: config key {materials.short(repr(key))} matches no material")
    return 0
