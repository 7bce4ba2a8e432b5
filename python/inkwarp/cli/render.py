"""``inkwarp render``: a scene to a PNG, a PNG sequence, a GIF, an MP4, video with alpha
(WebM, MOV, APNG) or a sprite sheet, in one process or on a Ray cluster."""

from __future__ import annotations

import argparse
import contextlib
import re
import sys
import time
import warnings
from collections.abc import Iterator

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp render scene.json -o anim.mp4                 every frame, H.264
  inkwarp render scene.json -o anim.gif --frames 0:24   frames 0 to 23
  inkwarp render scene.json -o frames/                  frame_0000.png, frame_0001.png, ...
  inkwarp render scene.json -o frames/ --frames 24:48   frame_0024.png to frame_0047.png
  inkwarp render scene.json -o still.png --time 1.25
  inkwarp render scene.json -o still.png --frame 30 --method triangulation
  inkwarp render scene.json -o anim.webm --background transparent   VP9 with alpha
  inkwarp render scene.json -o anim.mov                 ProRes 4444 (alpha kept)
  inkwarp render scene.json -o sheet.png --sprite-sheet 8x4   atlas + sheet.json
  inkwarp render scene.json -o frames/ --frames 0:100 --skip-existing   a farm chunk
  inkwarp render scene.json -o anim.mp4 --ray           on a local Ray cluster
  inkwarp render scene.json -o anim.mp4 --ray 10.0.0.5:6379   on a running cluster

The output's suffix picks the format: .png (one frame: --time or --frame, default frame
0), .gif, .mp4, .webm (VP9, alpha), .mov (ProRes 4444, alpha), .apng (alpha), or a
directory (a path ending in / or without a suffix). A scene whose background has alpha 0
(or --background transparent) keeps its alpha in PNGs, .webm, .mov and .apng, and gets
1-bit transparency in a .gif; .mp4 is flattened over white (with a warning where a frame
shows through). Frame i is
the drawing at time i / fps; frames are the same however a render is split into --frames
ranges or Ray chunks. The output is written under a temporary name and renamed at the
end, so a failed or interrupted render leaves nothing behind.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "render", help="render a scene to a PNG, PNG frames, GIF, MP4, WebM, MOV, APNG or sprite sheet",
        description="Render a scene: one frame to a PNG, or its frames to a directory of PNGs,\n"
                    "an animated GIF, an H.264 MP4, video with alpha (WebM, MOV, APNG) or a\n"
                    "sprite sheet; on this machine or on a Ray cluster.",
        epilog=EPILOG, formatter_class=_common.formatter)
    _common.add_scene_argument(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="where to write: FILE.png, .gif, .mp4, .webm, .mov, .apng or a "
                             "DIRECTORY/")
    one = parser.add_mutually_exclusive_group()
    one.add_argument("--time", type=float, metavar="T",
                     help="for a .png: the time in seconds of the frame to render")
    one.add_argument("--frame", type=int, metavar="N",
                     help="for a .png: the number of the frame to render (from 0; the same pixels "
                          "as that frame of a sequence or chunked render)")
    parser.add_argument("--frames", metavar="A:B",
                        help="for an animation: render frames A to B-1 only (default: all)")
    _common.add_method_argument(parser)
    parser.add_argument("--background", metavar="COLOR",
                        help="the background instead of the scene's: transparent, white, "
                             "black, #RRGGBB, #RRGGBBAA or R,G,B[,A]")
    parser.add_argument("--sprite-sheet", nargs="?", const="auto", metavar="COLSxROWS",
                        help="with -o SHEET.png: every frame on one atlas, and SHEET.json "
                             "(TexturePacker hash) beside it (default: a square grid)")
    parser.add_argument("--skip-existing", action="store_true",
                        help="with -o DIR/: leave frames already there alone, write each new "
                             "frame as soon as it is done (for render farms)")
    parser.add_argument("--ray", nargs="?", const="local", metavar="ADDRESS",
                        help="render on a Ray cluster, in contiguous chunks; without ADDRESS "
                             "on the one RAY_ADDRESS names or 'ray start' runs here, else on "
                             "one started for the render (needs inkwarp[ray])")
    parser.add_argument("--strict", action="store_true",
                        help="exit with status 3 when a solve did not converge (the output is "
                             "still written and the warnings printed), so a farm can tell")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="print nothing on success (no progress bar, no summary)")
    parser.set_defaults(func=run)


@contextlib.contextmanager
def convergence_lines(command: str = "render") -> Iterator[list[str]]:
    """Shows each solve that did not converge as one line on stderr (the first of each
    layer as it happens, then how many more there were), and every other inkwarp warning
    as one line, not as a Python warning, for `inkwarp COMMAND`. Yields the list of those
    solves' warnings, filled as they come (for ``--strict``)."""
    from inkwarp.errors import ConvergenceWarning, InkwarpWarning, PastEndWarning

    seen: set[str] = set()
    more: list[str] = []  # where the solves after each layer's first did not converge
    stopped: list[str] = []

    def show(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
        if not issubclass(category, InkwarpWarning):
            return shown(message, category, filename, lineno, file, line)
        text = str(message)
        if issubclass(category, PastEndWarning):
            return None  # said of --time in the command's own words (_common.warn_past_end)
        if not issubclass(category, ConvergenceWarning):
            _common.say(f"inkwarp {command}: warning: {text}")
            return None
        stopped.append(text)
        layer = text.split(" at t = ")[0]
        if layer in seen:
            found = re.search(r"\(frame (\d+)\)", text)
            more.append(found.group(1) if found else text.split(" at t = ")[1].split(":")[0])
        else:
            seen.add(layer)
            _common.say(f"inkwarp {command}: warning: {text}")

    with warnings.catch_warnings():
        warnings.simplefilter("always", InkwarpWarning)
        shown = warnings.showwarning
        warnings.showwarning = show
        try:
            yield stopped
        finally:
            if more:
                # Each frame once, in order (a frame where several layers stopped is one).
                frames = sorted({int(a) for a in more if a.isdigit()})
                where = [f"frame{'s' if len(frames) > 1 else ''} " + ", ".join(map(str, frames[:20]))
                         + (", …" if len(frames) > 20 else "")] if frames else []
                where += [f"t = {a}" for a in sorted({a for a in more if not a.isdigit()})[:5]]
                print(f"inkwarp {command}: warning: {len(more)} more solve{'s' if len(more) != 1 else ''} "
                      f"did not converge ({'; '.join(where)})", file=sys.stderr, flush=True)


#: The exit status of ``--strict`` when a solve did not converge.
NOT_CONVERGED = 3


def run(args: argparse.Namespace) -> int:
    with convergence_lines() as stopped:
        code = _run(args)
    return NOT_CONVERGED if code == 0 and args.strict and stopped else code


def _run(args: argparse.Namespace) -> int:
    from inkwarp import outputs, rendering, video

    kind = video.output_kind(args.output)
    target = video.check_target(args.output, kind)
    if kind == "png" and args.sprite_sheet is None:  # (animations are checked by rendering.render)
        outputs.check_not_an_input(target, args.scene)
    if args.sprite_sheet is not None:
        if kind == "dir" and target.suffix.lower() == ".png":
            raise ValueError(f"{target}: is a folder; --sprite-sheet writes one .png atlas (and a .json "
                             f"beside it): name a new file, such as {target / 'sheet.png'}")
        if kind != "png":
            raise ValueError(f"--sprite-sheet writes a .png atlas (and a .json beside it); "
                             f"name the output sheet.png, not {target.name}")
        outputs.check_sheet_json(target, args.scene)
        kind = "sheet"
    if kind == "png" and args.frames is not None:
        raise ValueError(f"--frames {args.frames}: a .png holds one frame; pick it with "
                         "--frame N or --time T, or write a .gif, an .mp4 or a directory")
    if kind != "png" and (args.time is not None or args.frame is not None):
        option = "--time" if args.time is not None else "--frame"
        if kind == "dir" and target.suffix.lower() == ".png" and target.is_dir():
            raise ValueError(f"{args.output}: is a folder (a folder takes a sequence's PNG frames); "
                             f"{option} writes one .png file: name one that is not a folder, or remove it")
        raise ValueError(f"{option} picks one frame, which goes to a .png (-o frame.png); "
                         f"for part of an animation use --frames A:B")
    if args.time is not None:
        _common.check_time(args.time)
    if args.skip_existing and kind != "dir":
        raise ValueError("--skip-existing works with a directory of PNG frames (-o DIR/), "
                         "whose frames are separate files")
    if args.ray is not None and kind == "png":
        # (A farm's job template may pass --ray to every render.)
        if not args.quiet:
            print("inkwarp render: note: --ray renders animations; one .png frame renders on this machine",
                  file=sys.stderr, flush=True)
        args.ray = None
    background = outputs.parse_background(args.background) if args.background is not None else None

    scene = _common.load_scene(args.scene)
    if background is not None:
        scene = outputs.with_background(scene, background)
    if args.method not in (None, "tps") and not args.quiet:
        torn = _torn_layers(scene)
        if torn:
            print(f"inkwarp render: note: --method {args.method} ignores the continuity matte and cuts: "
                  f"{', '.join(torn)} stay{'s' if len(torn) == 1 else ''} whole across {'its' if len(torn) == 1 else 'their'} "
                  "holes and cuts (only tps tears them)", file=sys.stderr, flush=True)
    if not args.quiet:
        # A key after the end (or before the start) cuts the animation short, one far off the
        # picture smears it (a still frame too): said here too, not only by validate.
        for path, message in scene._outside_keys(still=kind == "png"):
            print(f"inkwarp render: note: {_common.prefixed(_common.prefixed(message, path), args.scene)}",
                  file=sys.stderr, flush=True)
    started = time.perf_counter()
    if kind == "png":
        if args.time is not None:
            _common.warn_past_end("render", args.time, scene, "the frame shows")
            frame = scene.render(time=args.time, method=args.method)
            what = f"t = {args.time:g} s"
        else:
            # Through its warm-start chain, as a sequence renders it: the same pixels as that
            # frame of any chunked or sequential render (docs/guides/render-farm.md).
            index = _common.check_frame(args.frame or 0, scene.frame_count)
            (_, frame), = rendering.render_range(scene, index, index + 1, method=args.method, threads=1)
            what = f"frame {index}"
        with video.open_writer(target, fps=scene.fps, kind="png") as writer:
            writer.write(frame)
        if not args.quiet:
            print(f"wrote {target} ({what}, {_common.scene_size(scene)}) in "
                  f"{time.perf_counter() - started:.2f} s")
        return 0

    if kind == "dir" and args.frames is not None and _past_the_end(args.frames, scene.frame_count):
        # A farm's chunks of a fixed size may run wholly past the end: nothing to do, and no failed job.
        print(f"inkwarp render: warning: --frames {args.frames} starts past the scene's last frame "
              f"({scene.frame_count - 1}): no frame to render", file=sys.stderr, flush=True)
        return 0
    start, stop = (_common.parse_frames(args.frames, scene.frame_count, command="render")
                   if args.frames is not None else (0, scene.frame_count))
    if kind == "sheet":  # refused here in the command line's words, before rendering
        layout = None if args.sprite_sheet == "auto" else args.sprite_sheet
        outputs.check_sheet_size(*outputs.sheet_layout(stop - start, layout, size=(scene.width, scene.height)),
                                 scene.width, scene.height, layout)
    # The output as given: a trailing / makes shot_v1.2/ a directory.
    said = rendering.RAY_OPTION.set("--ray")  # (messages name the option as given here)
    try:
        paths = rendering.render(scene, args.output, frames=(start, stop), method=args.method,
                                 sprite_sheet=args.sprite_sheet, skip_existing=args.skip_existing,
                                 ray=args.ray, progress=not args.quiet)
        count = stop - start
        if not args.quiet:
            seconds = time.perf_counter() - started
            where = " on Ray" if args.ray is not None else ""
            if args.skip_existing:
                done = len(paths)
                print(f"wrote {done} new frame{'s' if done != 1 else ''} of {start}:{stop} into "
                      f"{target} ({count - done} already there){where} in {seconds:.2f} s")
            else:
                also = f" and {paths[1]}" if kind == "sheet" else ""
                size = _common.scene_size(scene)
                if kind == "mp4" and (scene.width % 2 or scene.height % 2):  # H.264 wants even sides
                    size += f" padded to {scene.width + scene.width % 2}x{scene.height + scene.height % 2}"
                print(f"wrote {target}{also} ({count} frame{'s' if count != 1 else ''} "
                      f"{start}:{stop}, {size}, {scene.fps:g} fps){where} in "
                      f"{seconds:.2f} s ({count / max(seconds, 1e-9):.1f} frames/s)")
    finally:
        # Ray left here, after the summary (its shutdown is no part of the render's time).
        rendering.RAY_OPTION.reset(said)
        if args.ray is not None:
            rendering.ray_shutdown()
    return 0


def _past_the_end(spec: str, frame_count: int) -> bool:
    """Whether ``--frames A:B`` is a range (A < B) that starts at or past ``frame_count``
    (not ``A`` alone, which is no range: said so by :func:`_common.parse_frames`)."""
    first, colon, last = spec.strip().partition(":")
    if not colon:
        return False
    try:
        start, stop = int(first), (int(last) if last.strip() else None)
    except ValueError:
        return False
    return start >= frame_count and (stop is None or stop > start)


def _torn_layers(scene) -> list[str]:
    """The layers whose grid a cut or a hole tears, as "layer 'NAME'"."""
    return [f"layer {name!r}" for name, torn in zip(scene.layers, scene._core.torn_layers()) if torn]
