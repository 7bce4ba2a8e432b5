"""The ``inkwarp`` command line.

Each command lives in a module of this package that defines ``add_parser(subparsers)``
(which registers the command and sets ``func``). Exit codes: 0 success, 2 bad input (one
clear message, no traceback), 1 internal error.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from inkwarp.errors import InkwarpError

# The command modules, in the order `inkwarp --help` lists them.
COMMANDS: list[str] = ["compare", "transfer"]


def build_parser() -> argparse.ArgumentParser:
    from inkwarp import __version__

    parser = argparse.ArgumentParser(
        prog="inkwarp",
        description="Animate a still image by animating a drawing traced over it.",
    )
    parser.add_argument("--version", action="version", version=f"inkwarp {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"inkwarp.cli.{name}").add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (InkwarpError, ValueError, FileNotFoundError) as err:
        print(f"inkwarp {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"inkwarp {args.command}: interrupted", file=sys.stderr)
        return 130
