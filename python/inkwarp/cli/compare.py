"""``inkwarp compare``: the same drawing through every interpolant, on one sheet."""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

EXAMPLE = """\
examples:
  inkwarp compare examples/checkerboard-hole/with-hole.json --time 2 -o sheet.png
  inkwarp compare scene.json --methods tps,beier-neely -o sheet.png
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "compare",
        help="compare the interpolants on a scene, as one sheet",
        description="Render a scene's frame with each method (tps, tps-exact, triangulation, "
        "beier-neely) and write one sheet: a row per method with the warped frame and its "
        "drawing, and the ΔX surface as a hill-shaded height map.",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("scene", metavar="SCENE", help="the scene file")
    parser.add_argument("--time", type=float, default=None, metavar="T",
                        help="the time in seconds (default: the scene's end)")
    parser.add_argument("--methods", default="tps,tps-exact,triangulation,beier-neely",
                        help="comma-separated methods, in row order (default: all four)")
    parser.add_argument("--layer", default=None, help="the layer whose ΔX is drawn (default: the first)")
    parser.add_argument("-o", "--output", required=True, metavar="SHEET.png", help="the sheet to write")
    parser.add_argument("--dpi", type=int, default=100, help="resolution of the sheet (default 100)")
    parser.add_argument("--quiet", action="store_true", help="print nothing on success")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp import Scene
    from inkwarp.compare import compare, comparison_sheet

    out = Path(args.output)
    if out.suffix.lower() != ".png":
        raise ValueError(f"the sheet {out} must be a .png file.")
    scene = Scene.load(args.scene)
    time = args.time if args.time is not None else float(getattr(scene, "duration", 0.0) or 0.0)
    comparison = compare(scene, time, args.methods, layer=args.layer)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{out.stem}.", suffix=".png", dir=out.parent)
    os.close(fd)
    try:
        comparison_sheet(comparison, tmp, title=f"{Path(args.scene).name}, t = {time:g} s", dpi=args.dpi)
        os.replace(tmp, out)
    except BaseException:
        os.unlink(tmp)
        raise
    if not args.quiet:
        for method in comparison.methods:
            for note in comparison.notes.get(method, []):
                print(f"{method}: {note}")
        print(f"wrote {out}")
    return 0
