"""``inkwarp track``: follow a scene's drawing through a video."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from inkwarp.cli._common import formatter, warnings_as_lines

EXAMPLE = """\
examples:
  inkwarp track actor.mp4 --scene actor.json -o actor-tracked.json
  inkwarp track actor.mp4 --scene actor.json --simplify 0.5 -o actor-tracked.json

SCENE's drawing (its features' rest geometry) is traced over frame K of the video, in a
scene of the video's size ('inkwarp frame VIDEO --frame K -o frame.png' gives the picture). OUT is SCENE with the video's fps and duration and, for every
feature but the cuts, a key at every video frame (t = k / fps). Keys SCENE already has at other frames
are corrections: the track passes through them. See docs/guides/rotoscoping.md.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "track",
        help="track a drawing traced on one frame through a video",
        description="Track the scene's drawing, traced over one frame of the video, through "
        "every frame (dense DIS flow refined by Lucas-Kanade, checked forward and backward, "
        "regularised by the thin plate) and write the scene with a key at every frame.",
        epilog=EXAMPLE,
        formatter_class=formatter,
    )
    parser.add_argument("video", metavar="VIDEO", help="the footage (any video ffmpeg reads)")
    parser.add_argument("--scene", required=True, metavar="SCENE",
                        help="the drawing traced over frame K (a scene of the video's size)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="where to write the tracked scene (.json)")
    parser.add_argument("--frame", type=int, default=0, metavar="K",
                        help="the video frame the drawing is traced on (default 0)")
    parser.add_argument("--simplify", type=float, default=None, metavar="PX",
                        help="keep only the keys needed for linear interpolation to stay "
                        "within PX pixels of every frame (default: a key at every frame)")
    parser.add_argument("--lost", type=float, default=2.0, metavar="PX",
                        help="warn about a feature at the frames where its points' median "
                        "forward-backward error is over PX pixels, or one of its control points "
                        "is found PX off (drift from the traced frame, off the picture) (default 2)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp.track import as_option, check_output, read_video, save_json, track_dict

    out = Path(args.output)
    if out.suffix.lower() != ".json":
        raise ValueError(f"the output {out} must be a .json scene file.")
    if not (math.isfinite(args.lost) and args.lost > 0):
        raise ValueError(f"--lost {args.lost}: give a distance in pixels above 0")
    if args.simplify is not None and not (math.isfinite(args.simplify) and args.simplify >= 0):
        raise ValueError(f"--simplify {args.simplify}: give a distance in pixels, 0 or more")
    check_output(out, source=args.scene)

    def progress(total: int):
        if args.quiet or total <= 1:
            return None
        from inkwarp.cli._common import progress_bar

        bar = progress_bar(total, "inkwarp track")
        bars.append(bar)
        return lambda: bar.update(1)

    bars: list = []
    with warnings_as_lines("track"):
        try:
            clip = read_video(args.video)
            doc = track_dict(clip, args.scene, args.frame, simplify_px=args.simplify,
                             lost_px=args.lost, progress=progress,
                             relative_to=out.resolve().parent)
        except ValueError as err:
            raise as_option(err, args.frame) from None
        finally:
            for bar in bars:
                bar.close()
    save_json(doc, out)
    if not args.quiet:
        keys = sum(len(f.get("keys", [])) for f in doc.get("features", []))
        print(f"wrote {out} ({len(doc.get('features', []))} features, {len(clip)} frames at "
              f"{clip.fps:g} fps, {keys} keys)")
    return 0
