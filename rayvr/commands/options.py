"""`rayvr options`: every render option, from its declaration (rayvr/options.py)."""
from __future__ import annotations

import json

from .. import options, settings as settings_mod


def add_parser(sub) -> None:
    o = sub.add_parser("options", help="list every render option: flag, type, default, allowed values, scope, "
                                       "the commands that offer it, where it is declared")
    o.add_argument("names", nargs="*", help="only these options")
    o.add_argument("--json", action="store_true")
    o.set_defaults(func=cmd_options)


def cmd_options(args) -> int:
    known = settings_mod.all_options()
    unknown = [n for n in args.names if n not in known]
    if unknown:
        raise ValueError(f"unknown render option(s) {', '.join(unknown)}; allowed: {', '.join(known)}")
    chosen = [known[n] for n in args.names] if args.names else list(known.values())
    if args.json:
        print(json.dumps([o.describe() for o in chosen], indent=1))
    else:
        print(options.listing(chosen), end="")
    return 0
