"""``inkwarp new``: a scene started from a picture (PNG, JPEG, WebP or layered PSD), with an
optional SVG drawing traced over it."""

from __future__ import annotations

import argparse
import math
import sys

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp new character.psd -o character.json
  inkwarp new character.psd -o character.json --drawing tracing.svg
  inkwarp new photo.jpg -o photo.json --embed --fps 12 --duration 3

A PNG, JPEG or WebP picture gives one layer; a PSD gives one layer per pixel layer, in the
PSD's order, with its name and visibility, each a canvas-sized image (groups are flattened
into their layers; layers whose blend mode is not Normal are reported). The layers'
images are written beside the scene as SCENE-LAYER.png (a PNG or JPEG picture is used
where it is, unless it carries a colour profile other than sRGB's: it is converted to sRGB,
as a viewer shows it), or into the scene as data: URIs with --embed. A picture's kind is
read from its contents, not its name (a WebP saved as .jpg is converted as a .webp is). An SVG drawing's shapes
become features: closed filled shapes regions, open paths splines or polylines, ids or
classes with "cut" cuts, small circles points (docs/guides/psd-and-svg.md). The scene's
background is transparent, so frame 0 is the picture as it is.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "new", help="start a scene from a picture or a layered PSD (and an SVG drawing)",
        description="Start a scene from a picture: one layer for a PNG, JPEG or WebP, one\n"
                    "layer per pixel layer for a PSD; an SVG traced over it gives the drawing.",
        epilog=EPILOG, formatter_class=_common.formatter)
    parser.add_argument("picture", metavar="PICTURE", help="a .png, .jpg (.jpeg, .jfif, .jpe), .webp or .psd file")
    parser.add_argument("-o", "--output", required=True, metavar="SCENE",
                        help="the scene file to write (.json)")
    parser.add_argument("--drawing", metavar="SVG",
                        help="an SVG drawing traced over the picture: its shapes become features")
    parser.add_argument("--embed", action="store_true",
                        help="put the layers' images into the scene as data: URIs")
    parser.add_argument("--fps", type=float, default=24.0, metavar="FPS",
                        help="frames per second (default: 24)")
    parser.add_argument("--duration", type=float, default=2.0, metavar="S",
                        help="length in seconds (default: 2)")
    parser.add_argument("--force", action="store_true",
                        help="replace the scene (and its layer images) if they already exist")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="print no notes and no summary")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp.importing import write_new_scene

    from inkwarp.errors import InkwarpError, SceneError

    if not (math.isfinite(args.duration) and args.duration > 0):
        raise ValueError(f"--duration {args.duration}: give a length in seconds > 0, such as 2")
    try:
        paths, notes = write_new_scene(args.picture, args.output, drawing=args.drawing,
                                       embed=args.embed, fps=args.fps, duration=args.duration,
                                       force=args.force)
    except SceneError as err:
        # The scene's limits on what the options set (1000 frames per second, ...) are the options'.
        if err.problems and all(path in ("fps", "duration") for path, _ in err.problems):
            raise ValueError("; ".join(f"--{path} {getattr(args, path):g}: {why}" for path, why in err.problems)) from None
        raise
    if not args.quiet:
        for note in notes:
            print(f"inkwarp new: note: {note}", file=sys.stderr)
        # What validate would note of the new scene (a traced feature off the picture or on
        # its transparent pixels), said now rather than at the first render.
        from inkwarp.cli._common import prefixed
        from inkwarp.scene import Scene

        # (The scene is written: a failure to read it back, a file removed at once, is not this command's.)
        try:
            written = Scene.load(paths[-1]).notes()
        except (InkwarpError, OSError):
            written = []
        for path, message in written:
            print(f"inkwarp new: note: {prefixed(prefixed(message, path), str(paths[-1]))}", file=sys.stderr)
        images = len(paths) - 1
        print(f"wrote {paths[-1]}" + (f" and {images} layer image{'s' if images != 1 else ''}"
                                      if images else ""))
    return 0
