"""``inkwarp demo``: render the examples and the still demo, and print every path."""

from __future__ import annotations

import argparse

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp demo                       everything into out/
  inkwarp demo -o /tmp/demo --only face --formats gif

It renders, into DIR: the still demo (before.png, after.png, field.png, matte.png: a
generated picture warped by a curve, a point and a hole in its matte) and the example
scenes (face, cat, checkerboard-hole with and without its hole, the comparison plates,
the transfer and the rotoscoping pipeline) as GIF and MP4. The examples are read from the
source checkout, else from the copy a wheel ships; --examples points elsewhere.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    from inkwarp import demo

    parser = subparsers.add_parser(
        "demo", help="render the still demo and the example animations",
        description="Render the still demo and the example scenes as GIF and MP4, and print\n"
                    "the path of every file written.",
        epilog=EPILOG, formatter_class=_common.formatter)
    parser.add_argument("-o", "--output", default="out", metavar="DIR",
                        help="the directory to write into, created if missing (default: out)")
    parser.add_argument("--only", action="append", metavar="NAME",
                        choices=["stills", *demo.EXAMPLES, *demo.EXTRA_PARTS],
                        help="render only this part (repeatable): stills, "
                             + ", ".join([*demo.EXAMPLES, *demo.EXTRA_PARTS]))
    parser.add_argument("--formats", default="gif,mp4", metavar="LIST",
                        help="the animation formats, comma-separated: gif, mp4 "
                             "(default: gif,mp4)")
    parser.add_argument("--examples", metavar="DIR",
                        help="where the example scenes are (default: examples/ of the source "
                             "checkout this package runs from)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bars (the paths are still printed)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp import demo
    from inkwarp.cli.render import convergence_lines

    formats = [f.strip().lower() for f in args.formats.split(",") if f.strip()]
    # Warnings (the rotoscope example's lost track) as one line each, as `inkwarp render`
    # and `inkwarp track` show them, not as Python warnings.
    with convergence_lines("demo"):
        demo.run(args.output, only=args.only, formats=formats, examples_dir=args.examples,
                 quiet=args.quiet)
    return 0
