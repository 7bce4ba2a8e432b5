"""``inkwarp render``: a scene to a PNG, a PNG sequence, a GIF or an MP4."""

from __future__ import annotations

import argparse
import time

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp render scene.json -o anim.mp4                 every frame, H.264
  inkwarp render scene.json -o anim.gif --frames 0:24   frames 0 to 23
  inkwarp render scene.json -o frames/                  frame_0000.png, frame_0001.png, ...
  inkwarp render scene.json -o frames/ --frames 24:48   frame_0024.png to frame_0047.png
  inkwarp render scene.json -o still.png --time 1.25
  inkwarp render scene.json -o still.png --frame 30 --method triangulation

The output's suffix picks the format: .png (one frame: --time or --frame, default frame
0), .gif, .mp4, or a directory (a path ending in / or without a suffix). Frame i is the
drawing at time i / fps. The output is written under a temporary name and renamed at the
end, so a failed or interrupted render leaves nothing behind.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "render", help="render a scene to a PNG, a PNG sequence, a GIF or an MP4",
        description="Render a scene: one frame to a PNG, or its frames to a directory of PNGs,\n"
                    "an animated GIF or an H.264 MP4.",
        epilog=EPILOG, formatter_class=_common.formatter)
    _common.add_scene_argument(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="where to write: FILE.png, FILE.gif, FILE.mp4 or a DIRECTORY/")
    one = parser.add_mutually_exclusive_group()
    one.add_argument("--time", type=float, metavar="T",
                     help="for a .png: the time in seconds of the frame to render")
    one.add_argument("--frame", type=int, metavar="N",
                     help="for a .png: the number of the frame to render (from 0)")
    parser.add_argument("--frames", metavar="A:B",
                        help="for an animation: render frames A to B-1 only (default: all)")
    _common.add_method_argument(parser)
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="print nothing on success (no progress bar, no summary)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp import video

    target = video.check_target(args.output)
    kind = video.output_kind(args.output)
    if kind == "png" and args.frames is not None:
        raise ValueError(f"--frames {args.frames}: a .png holds one frame; pick it with "
                         "--frame N or --time T, or write a .gif, an .mp4 or a directory")
    if kind != "png" and (args.time is not None or args.frame is not None):
        option = "--time" if args.time is not None else "--frame"
        raise ValueError(f"{option} picks one frame, which goes to a .png (-o frame.png); "
                         f"for part of an animation use --frames A:B")
    if args.time is not None:
        _common.check_time(args.time)

    scene = _common.load_scene(args.scene)
    started = time.perf_counter()
    if kind == "png":
        if args.time is not None:
            frame = scene.render(time=args.time, method=args.method)
            what = f"t = {args.time:g} s"
        else:
            index = _common.check_frame(args.frame or 0, scene.frame_count)
            frame = scene.render(frame=index, method=args.method)
            what = f"frame {index}"
        with video.open_writer(target, fps=scene.fps, kind="png") as writer:
            writer.write(frame)
        if not args.quiet:
            print(f"wrote {target} ({what}, {_common.scene_size(scene)}) in "
                  f"{time.perf_counter() - started:.2f} s")
        return 0

    start, stop = (_common.parse_frames(args.frames, scene.frame_count)
                   if args.frames is not None else (0, scene.frame_count))
    count = stop - start
    frames = _common.progress(scene.frames(start=start, stop=stop, method=args.method), count,
                              quiet=args.quiet,
                              desc=f"render {target.name or target}")
    with video.open_writer(target, fps=scene.fps, kind=kind, first_frame=start) as writer:
        for frame in frames:
            writer.write(frame)
        if writer.frames_written != count:  # never half a clip under the full clip's name
            raise RuntimeError(f"the scene gave {writer.frames_written} frames for "
                               f"{start}:{stop}")
    if not args.quiet:
        seconds = time.perf_counter() - started
        print(f"wrote {target} ({count} frame{'s' if count != 1 else ''} {start}:{stop}, "
              f"{_common.scene_size(scene)}, {scene.fps:g} fps) in {seconds:.2f} s "
              f"({count / max(seconds, 1e-9):.1f} frames/s)")
    return 0
