"""``inkwarp field``: the displacement field of a scene at one time, as NumPy or a picture."""

from __future__ import annotations

import argparse
import io
import sys
import time
from pathlib import Path

import numpy as np

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp field scene.json --time 1.0 -o field.npy
  inkwarp field scene.json --frame 24 --layer face -o face_field.npy
  inkwarp field scene.json --time 1.0 -o field.png     the field as a picture

A .npy holds float32 (H, W, 2): [..., 0] is dx and [..., 1] is dy in pixels, defined on
the rest image (pixel (x, y) moves to (x + dx, y + dy)). Load it with numpy.load. A .png
shows it: hue is the direction, saturation the length, arrows the motion.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "field", help="write a scene's displacement field at one time (.npy or .png)",
        description="Write the displacement field that a scene's drawing makes at one time:\n"
                    "float32 (H, W, 2) to a .npy, or a picture of it to a .png.",
        epilog=EPILOG, formatter_class=_common.formatter)
    _common.add_scene_argument(parser)
    parser.add_argument("-o", "--output", required=True, metavar="FIELD",
                        help="where to write: FIELD.npy (the numbers) or FIELD.png (a picture)")
    when = parser.add_mutually_exclusive_group(required=True)
    when.add_argument("--time", type=float, metavar="T", help="the time in seconds")
    when.add_argument("--frame", type=int, metavar="N",
                      help="the frame number (from 0), instead of --time")
    parser.add_argument("--layer", metavar="NAME",
                        help="the layer whose field to write (each layer has its own; needed "
                             "when the scene has more than one)")
    _common.add_method_argument(parser)
    parser.add_argument("--strict", action="store_true",
                        help="exit with status 3 when the solve did not converge (the field is "
                             "still written)")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp.cli.render import NOT_CONVERGED, convergence_lines

    with convergence_lines("field") as stopped:
        code = _run(args)
    return NOT_CONVERGED if code == 0 and args.strict and stopped else code


def _run(args: argparse.Namespace) -> int:
    from inkwarp import video

    target = Path(args.output)
    suffix = target.suffix.lower()
    if suffix not in (".npy", ".png"):
        raise ValueError(f"{target}: name the output .npy (the field as numbers) or .png "
                         "(a picture of it)")
    from inkwarp import outputs

    video.check_file(target)
    outputs.check_not_an_input(target, args.scene, "field")
    scene = _common.load_scene(args.scene)
    if args.time is not None:
        time_s = _common.check_time(args.time)
        _common.warn_past_end("field", args.time, scene, "the field is")
    else:
        time_s = _common.check_frame(args.frame, scene.frame_count) / scene.fps
    names = scene.layers
    if args.layer is None and len(names) > 1:
        raise ValueError(f"{args.scene}: the scene has {len(names)} layers ({', '.join(names)}), each with "
                         "its own field; choose one with --layer NAME")
    _common.check_layer(args.scene, args.layer, names)
    started = time.perf_counter()
    field = np.asarray(scene.field(time=time_s, layer=args.layer, method=args.method),
                       dtype=np.float32)
    if suffix == ".npy":
        buffer = io.BytesIO()
        np.save(buffer, field)
        video.write_bytes(target, buffer.getvalue())
    else:
        with video.open_writer(target, kind="png") as writer:
            writer.write(video.field_picture(field))
    if not args.quiet:
        length = np.hypot(field[..., 0], field[..., 1])
        layer = f", layer {args.layer}" if args.layer else ""
        print(f"wrote {target} (t = {time_s:g} s{layer}, {field.shape[1]}x{field.shape[0]}, "
              f"largest move {float(length.max()):.2f} px) in "
              f"{time.perf_counter() - started:.2f} s")
    return 0
