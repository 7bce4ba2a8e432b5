"""``inkwarp compare``: the same drawing through every interpolant, on one sheet."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

EXAMPLE = """\
examples:
  inkwarp compare examples/checkerboard-hole/with-hole.json --time 2 -o sheet.png
  inkwarp compare scene.json --methods tps,beier-neely -o sheet.png
  inkwarp compare scene.json --beier-neely a=4,p=0.5 --max-samples 300 -o sheet.png
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
    parser.add_argument("--layer", default=None,
                        help="the layer whose ΔX is drawn (default: the top layer that is drawn)")
    parser.add_argument("--beier-neely", default=None, metavar="a=A,b=B,p=P",
                        help="Beier–Neely's weights for every layer, any of a (px, > 0), b (≥ 0), p (≥ 0); "
                        "the others keep the scene's solver.beier_neely (default a=1,b=2,p=0)")
    parser.add_argument("--max-samples", default=None, type=int, metavar="N",
                        help="tps-exact fits at most N samples (1–5000), instead of the scene's "
                        "solver.tps_exact.max_samples (default 1000)")
    parser.add_argument("-o", "--output", required=True, metavar="SHEET.png", help="the sheet to write")
    parser.add_argument("--dpi", type=_dpi, default=100,
                        help="resolution of the sheet, 10 to 600 (default 100)")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    parser.set_defaults(func=run)


def _weights(text: str) -> dict[str, float]:
    """``a=4,p=0.5`` as ``{"a": 4.0, "p": 0.5}``."""
    out: dict[str, float] = {}
    for part in (p.strip() for p in text.split(",") if p.strip()):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or key not in ("a", "b", "p"):
            raise ValueError(f"--beier-neely takes a=A,b=B,p=P (any of them), not {part!r}.")
        try:
            out[key] = float(value)
        except ValueError:
            raise ValueError(f"--beier-neely: {key} must be a number, not {value.strip()!r}.") from None
    if not out:
        raise ValueError("--beier-neely takes at least one of a=A, b=B, p=P.")
    return out


def run(args: argparse.Namespace) -> int:
    from inkwarp import Scene
    from inkwarp.errors import SceneError
    from inkwarp.compare import compare, comparison_sheet

    out = Path(args.output)
    if out.suffix.lower() != ".png":
        raise ValueError(f"the sheet {out} must be a .png file.")
    from inkwarp import outputs, video

    video.check_file(out)
    outputs.check_not_an_input(out, args.scene, "comparison sheet")
    scene = Scene.load(args.scene)
    from inkwarp.cli._common import check_layer, check_time, warn_past_end

    check_layer(args.scene, args.layer, scene.layers)

    time = check_time(args.time) if args.time is not None else float(getattr(scene, "duration", 0.0) or 0.0)
    if args.time is not None:
        warn_past_end("compare", args.time, scene, "the sheet shows")
    try:
        comparison = compare(scene, time, args.methods, layer=args.layer, max_samples=args.max_samples,
                             **(_weights(args.beier_neely) if args.beier_neely is not None else {}))
    except SceneError as err:
        # The scene loaded, so settings out of range are the command line's, not its solver's.
        options = {"solver.beier_neely.": f"--beier-neely {args.beier_neely}", "solver.tps_exact.max_samples": "--max-samples"}
        named = [next((f"{option}: {message}" for where, option in options.items() if path.startswith(where)), None)
                 for path, message in err.problems]
        if None in named:
            raise
        raise ValueError("; ".join(dict.fromkeys(named))) from None
    from inkwarp._atomic import temp_path

    tmp = temp_path(out, ".png")
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


def _dpi(text: str) -> int:
    try:
        dpi = int(text)
    except ValueError:
        dpi = 0
    if not 10 <= dpi <= 600:
        raise argparse.ArgumentTypeError(f"{text}: give a whole number of dots per inch from 10 "
                                         "to 600, such as 100")
    return dpi
