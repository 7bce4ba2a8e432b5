"""``inkwarp frame``: one frame of a video as a PNG, the picture to trace a drawing on."""

from __future__ import annotations

import argparse
from pathlib import Path

from inkwarp.cli._common import formatter, warnings_as_lines

EXAMPLE = """\
examples:
  inkwarp frame actor.mp4 -o frame.png
  inkwarp frame actor.mp4 --frame 48 -o frame48.png

Trace the drawing over the picture (inkwarp edit opens a scene that names it as a layer's
image), then run inkwarp track with the same --frame.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "frame",
        help="write one frame of a video as a PNG (the picture to trace on)",
        description="Write frame K of the video as a PNG (RGBA, opaque: videos keep no alpha).",
        epilog=EXAMPLE,
        formatter_class=formatter,
    )
    parser.add_argument("video", metavar="VIDEO", help="the footage (any video ffmpeg reads)")
    parser.add_argument("--frame", type=int, default=0, metavar="K",
                        help="the frame number, from 0 (default 0)")
    parser.add_argument("-o", "--output", required=True, metavar="PNG", help="the picture to write")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp.imaging import write_png
    from inkwarp.track import as_option, check_output, read_frame

    out = Path(args.output)
    if out.suffix.lower() != ".png":
        raise ValueError(f"the output {out} must be a .png file.")
    check_output(out)
    with warnings_as_lines("frame"):
        try:
            rgb = read_frame(args.video, args.frame)
        except ValueError as err:
            raise as_option(err, args.frame) from None
    write_png(out, rgb)
    if not args.quiet:
        print(f"wrote {out} (frame {args.frame}, {rgb.shape[1]}x{rgb.shape[0]})")
    return 0
