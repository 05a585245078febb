"""The `rayvr` command: capture, info, bench, preview, options (one module each in rayvr/commands/)."""
from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys

from .options import PlanRefusal
from .util.extras import MissingExtraError
from .util.signals import handling


class OneLineErrors(argparse.ArgumentParser):
    """A usage error is one line, like every other rayvr error (argparse prints the whole usage
    first); exit status 2 as argparse's. Sub-commands get this class too."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} -h)\n")


def build_parser() -> argparse.ArgumentParser:
    from .commands import bench, capture, info, options, preview

    p = OneLineErrors(prog="rayvr", description="Hybrid raster + ray-traced stereo renderer for VR.")
    p.add_argument("-v", "--verbose", action="store_true", help="log what rayvr decides")
    sub = p.add_subparsers(dest="command", required=True)
    for command in (capture, info, bench, preview, options):
        command.add_parser(sub)
    return p


# The commands that render a scene: without --materials, the built-in room gets its own config there.
ROOM_COMMANDS = ("capture", "preview")
EXIT_INTERRUPTED = 130  # 128 + SIGINT, what a shell reports for a process Ctrl-C ended
EXIT_TERMINATED = 128 + signal.SIGTERM


@contextlib.contextmanager
def sigterm_as_interrupt():
    """While the command runs, SIGTERM (kill, a job scheduler) raises KeyboardInterrupt where the
    command is, so that it ends as Ctrl-C does: temporary files, and an output folder it made and
    left empty, are removed on the way. Yields a list that holds the signal once it came."""
    received = []

    def on_sigterm(signum, frame):
        received.append(signum)
        raise KeyboardInterrupt("terminated")

    with handling(signal.SIGTERM, on_sigterm):
        yield received


def main(argv=None) -> int:
    code = run_command(argv)
    from .app.cluster import connect_left_behind
    if argv is None and connect_left_behind():  # a process of its own: no exit handler may wait on Ray
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def tells_the_room(args) -> bool:
    """Whether the built-in room's one-line hint (scene/defaults.py ROOM_NOTICE) says something true and
    new: not with --quiet, not after --budget-ms replaced the room's config with its pick, not over a
    --views set (a dataset capture, not a first look)."""
    budget = getattr(args, "budget_ms", None) is not None or getattr(args, "budget_hz", None) is not None
    return not (getattr(args, "quiet", False) or budget or getattr(args, "views", None))


def run_command(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="rayvr: %(message)s")
    notice = None
    if getattr(args, "device", None) is not None:
        from .gl.context import EGL_DEVICE_ENV

        if getattr(args, "workers", None) or getattr(args, "address", None):
            print(f"rayvr {args.command}: error: --device picks one GPU for this process; with --workers or "
                  f"--address each Ray worker takes the GPU Ray gives it: leave out --device", file=sys.stderr)
            return 2
        os.environ[EGL_DEVICE_ENV] = str(args.device)  # every headless context of the command takes it
    if args.command in ROOM_COMMANDS:
        from .scene.defaults import materials_for

        args.materials, notice = materials_for(args.scene, args.materials)
    from .gl.context import ContextError
    from .scene.materials import ConfigError
    from .util.output import OutputError
    from .scene.loader import SceneError
    from .gl.shaders import ShaderError
    from .app.cluster import ClusterError

    with sigterm_as_interrupt() as sigterm:
        try:
            code = args.func(args)
            if notice and code == 0 and tells_the_room(args):  # after the work: an error stays one line
                print(notice, file=sys.stderr)
            return code
        except (ContextError, ConfigError, SceneError, OutputError, ShaderError, ClusterError, MissingExtraError,
                ValueError) as exc:
            words = exc.in_flags() if isinstance(exc, PlanRefusal) else exc  # the core names options, not flags
            print(f"rayvr {args.command}: error: {words}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: one line, the shell's status for the signal
            print(f"rayvr {args.command}: {str(exc) or 'interrupted'}", file=sys.stderr)
            return EXIT_TERMINATED if sigterm else EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
