"""``inkwarp validate``: every problem in a scene, or "ok" and what it holds."""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from typing import Any

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp validate scene.json

On success it prints one line, such as
  ok: scene.json: 384x384, 2 layers (eyes, face), 15 features (2 point, 3 polyline,
  10 spline), 60 frames at 24 fps (2.5 s)
then a line "note: FILE: JSON.PATH: ..." for each thing that is allowed but probably
a mistake (a feature wholly off the picture or on transparent pixels, a key after the
scene's end or far off the picture, a feature that drives no layer, a line or region
with no extent, a matte that falls apart on the coarse grid of its grid_step), and
exits 0.
Otherwise it prints each problem as
FILE: JSON.PATH: what is wrong and how to fix it, then the count, and exits 2.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "validate", help="check a scene: list every problem, or print a summary",
        description="Check a scene file: print every problem with its JSON path and the fix\n"
                    "(exit 2), or 'ok' with a summary of its layers, features and frames\n"
                    "(exit 0).",
        epilog=EPILOG, formatter_class=_common.formatter)
    _common.add_scene_argument(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp.errors import SceneError

    notes: list = []
    try:
        scene = _common.load_scene(args.scene)
        problems = [_common.problem_parts(p) for p in (scene.validate() or [])]
        notes = [] if problems else scene.notes()  # before "ok": a note's checks may still refuse the scene
    except SceneError as err:
        problems = [_common.problem_parts(p) for p in err.problems] or [(err.path, str(err))]
    def say(path: str, message: str, lead: str = "") -> None:
        print(" ".join((lead + _common.prefixed(_common.prefixed(message, path), args.scene)).split()))

    if problems:
        for path, message in problems:
            say(path, message)
        count = len(problems)
        print(f"{args.scene}: {count} problem{'s' if count > 1 else ''}", file=sys.stderr)
        return 2
    print(f"ok: {args.scene}: {summary(scene, _read_json(args.scene))}")
    for path, message in notes:
        say(path, message, "note: ")
    return 0


def summary(scene: Any, doc: dict[str, Any]) -> str:
    """One line: size, layers, features by kind, frames."""
    layers = [layer for layer in doc.get("layers") or [] if isinstance(layer, dict)]
    names = ", ".join(str(layer.get("name", f"#{i}")) for i, layer in enumerate(layers))
    features = [f for f in doc.get("features") or [] if isinstance(f, dict)]
    kinds = Counter(str(f.get("kind")) for f in features)
    by_kind = ", ".join(f"{n} {kind}" for kind, n in sorted(kinds.items()))
    parts = [
        _common.scene_size(scene),
        f"{len(layers)} layer{'s' if len(layers) != 1 else ''}" + (f" ({names})" if names else ""),
        f"{len(features)} feature{'s' if len(features) != 1 else ''}"
        + (f" ({by_kind})" if by_kind else ""),
        f"{scene.frame_count} frame{'s' if scene.frame_count != 1 else ''} at {scene.fps:g} fps "
        f"({scene.duration:g} s)",
    ]
    return ", ".join(parts)


def _read_json(path: str) -> dict[str, Any]:
    from inkwarp.scene import read_scene_text

    doc = json.loads(read_scene_text(path))
    return doc if isinstance(doc, dict) else {}
