"""What the commands share: loading a scene, picking frames and times, the progress bar."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Iterable, Iterator
from typing import Any

#: The surfaces a drawing can drive (DESIGN §6); ``tps`` is the grid thin plate.
METHODS = ("tps", "tps-exact", "triangulation", "beier-neely")


def formatter(prog: str) -> argparse.HelpFormatter:
    """Help that keeps the epilog's example lines as written."""
    return argparse.RawDescriptionHelpFormatter(prog, max_help_position=30)


def add_scene_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE", help="the scene file (JSON)")


def add_method_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--method", choices=METHODS, metavar="METHOD",
        help="the surface the drawing drives, instead of every layer's solver.method: "
             + ", ".join(METHODS) + " (default: the scene's, normally tps)")


def load_scene(path: str) -> Any:
    """``inkwarp.Scene`` from a file.

    The engine's errors pass through unchanged (a :class:`~inkwarp.SceneError` names the
    file and the JSON path); a missing file is a ``FileNotFoundError`` naming it.
    """
    import inkwarp

    if not os.path.exists(path):
        raise FileNotFoundError(2, "No such file or directory", path)
    if os.path.isdir(path):
        raise IsADirectoryError(21, "is a directory, not a scene file", path)
    return inkwarp.Scene.load(path)


def parse_frames(spec: str, frame_count: int) -> tuple[int, int]:
    """``(start, stop)`` of ``--frames A:B``: frames A, A+1, ..., B-1 (either end may be
    left out, as in a Python slice).

    Examples
    --------
    >>> parse_frames("10:20", 48), parse_frames(":12", 48), parse_frames("40:", 48)
    ((10, 20), (0, 12), (40, 48))
    """
    text = spec.strip()
    if ":" not in text:
        raise ValueError(f"--frames {spec}: write a range A:B (frames A to B-1), such as 0:24")
    first, _, last = text.partition(":")
    try:
        start = int(first) if first.strip() else 0
        stop = int(last) if last.strip() else frame_count
    except ValueError:
        raise ValueError(f"--frames {spec}: A and B must be whole frame numbers, such as 0:24"
                         ) from None
    if start < 0 or stop > frame_count or start >= stop:
        raise ValueError(f"--frames {spec}: the scene has frames 0 to {frame_count - 1}; give "
                         f"0 <= A < B <= {frame_count}")
    return start, stop


def check_time(time_s: float, option: str = "--time") -> float:
    if not math.isfinite(time_s) or time_s < 0:
        raise ValueError(f"{option} {time_s:g}: give a time in seconds from 0, such as 0.5")
    return time_s


def check_frame(frame: int, frame_count: int) -> int:
    if not 0 <= frame < frame_count:
        raise ValueError(f"--frame {frame}: the scene has frames 0 to {frame_count - 1}")
    return frame


def progress(frames: Iterable[Any], total: int, *, quiet: bool, desc: str) -> Iterator[Any]:
    """``frames`` with a progress bar on stderr (frames/s and time left) unless ``quiet``."""
    if quiet or total <= 1:
        yield from frames
        return
    from tqdm import tqdm

    with tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
              leave=True, smoothing=0.1,
              bar_format="{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} frames "
                         "[{elapsed}<{remaining}, {rate_fmt}]") as bar:
        for item in frames:
            yield item
            bar.update(1)


def scene_size(scene: Any) -> str:
    return f"{scene.width}x{scene.height}"


def problem_parts(problem: object) -> tuple[str, str]:
    """``(path, message)`` of one entry of ``SceneError.problems`` (a pair or an object)."""
    if isinstance(problem, (tuple, list)) and len(problem) == 2:
        return str(problem[0] or ""), str(problem[1])
    path = getattr(problem, "path", "") or ""
    message = getattr(problem, "message", None) or str(problem)
    return str(path), str(message)


def prefixed(message: str, prefix: str | None) -> str:
    """``prefix: message``, unless the message already starts that way."""
    if not prefix or message.startswith(f"{prefix}: "):
        return message
    return f"{prefix}: {message}"
