"""What the commands share: loading a scene, picking frames and times, the progress display."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import sys
import time
from collections.abc import Iterable, Iterator
from typing import Any

from inkwarp._inkwarp import MAX_TIME_S
from inkwarp.errors import InputError

#: The signals that end a command as Ctrl-C does: a scheduler's SIGTERM, and SIGHUP where
#: a terminal or session closes (left alone where it is ignored, as under ``nohup``).
UNWINDING = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))

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
    file and the JSON path); a missing file is
    :meth:`~inkwarp.Scene.load`'s ``MissingFileError`` naming it.
    """
    import inkwarp

    if os.path.isdir(path):
        raise IsADirectoryError(21, "is a directory, not a scene file", path)
    return inkwarp.Scene.load(path)


def given(option: str, value: object) -> str:
    """How a message quotes a value given: ``--frames 5:1`` for a command-line flag,
    ``frames='5:1'`` for a Python argument (``option`` without the dashes).

    Examples
    --------
    >>> given("--frames", "5:1"), given("frames", "5:1")
    ('--frames 5:1', "frames='5:1'")
    """
    return f"{option} {value}" if option.startswith("-") else f"{option}={value!r}"


def parse_frames(spec: str, frame_count: int, option: str = "--frames", command: str | None = None) -> tuple[int, int]:
    """``(start, stop)`` of ``--frames A:B``: frames A, A+1, ..., B-1 (either end may be
    left out, as in a Python slice; a B past the end is cut to it, as in a slice, so that a
    farm's fixed-size chunks end on the last frame). Messages name ``option`` (``"frames"``
    for Python's argument); with ``command``, a B past the end is said on stderr.

    Examples
    --------
    >>> parse_frames("10:20", 48), parse_frames(":12", 48), parse_frames("40:", 48), parse_frames("40:64", 48)
    ((10, 20), (0, 12), (40, 48), (40, 48))
    """
    text = spec.strip()
    if ":" not in text:
        raise InputError(f"{given(option, spec)}: write a range A:B (frames A to B-1), such as 0:24")
    first, _, last = text.partition(":")
    try:
        start = int(first) if first.strip() else 0
        stop = int(last) if last.strip() else frame_count
    except ValueError:
        raise InputError(f"{given(option, spec)}: A and B must be whole frame numbers, such as 0:24"
                         ) from None
    if start < 0 or start >= min(stop, frame_count):
        raise InputError(f"{given(option, spec)} is not a range of the scene, which has frames 0 to {frame_count - 1}; give "
                         f"0 <= A < B with A < {frame_count}")
    if stop > frame_count and command:
        print(f"inkwarp {command}: warning: {given(option, spec)} runs past the scene's last frame ({frame_count - 1}); "
              f"rendering {start}:{frame_count}", file=sys.stderr, flush=True)
    return start, min(stop, frame_count)


def check_time(time_s: float, option: str = "--time") -> float:
    """A time a scene holds, as the Python API takes it: within ±`MAX_TIME_S` (before 0 is
    the drawing before the first frame, where keys may lie)."""
    if not math.isfinite(time_s) or not -MAX_TIME_S <= time_s <= MAX_TIME_S:
        raise InputError(f"{option} {time_s:g}: give a time in seconds from {-MAX_TIME_S:g} to {MAX_TIME_S:g} "
                         "(about 27 hours), such as 0.5")
    return time_s


def warn_past_end(command: str, given: float, scene: Any, shows: str) -> None:
    """Warn on stderr when ``--time given`` is past the scene's end, or before its start and
    every key (keys may lie before 0 on purpose): what ``shows`` (such as "the frame shows")
    is the poses held after the last keys, or before the first."""
    if given > scene.duration:
        print(f"inkwarp {command}: warning: --time {given:g} is past the scene's end ({scene.duration:g} s); "
              f"{shows} the poses held after the last keys", file=sys.stderr, flush=True)
    elif scene._before_every_key(given):
        print(f"inkwarp {command}: warning: --time {given:g} is before the scene's start (0 s); "
              f"{shows} the poses held before the first keys", file=sys.stderr, flush=True)


def check_frame(frame: int, frame_count: int) -> int:
    if not 0 <= frame < frame_count:
        raise InputError(f"--frame {frame}: the scene has frames 0 to {frame_count - 1}")
    return frame


#: Without a terminal, a progress line is printed at most every this many seconds, and
#: only after this fraction of the frames more is done (whichever is less frequent).
PROGRESS_LINE_S = 30.0
PROGRESS_LINE_FRACTION = 0.1
_clock = time.monotonic


def _duration(seconds: float) -> str:
    """``M:SS`` or ``H:MM:SS``."""
    minutes, secs = divmod(int(round(seconds)), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class ProgressLines:
    """Progress as plain lines, for a stderr that is not a terminal (a log file, a farm's
    pipe), where a bar's carriage-return updates would pile up on one growing line: one
    line when at least :data:`PROGRESS_LINE_FRACTION` more of the frames is done and
    :data:`PROGRESS_LINE_S` have passed since the last one, and one at the end."""

    def __init__(self, total: int, desc: str) -> None:
        self.total, self.desc, self.n = total, desc, 0
        self._start = self._last_time = _clock()
        self._last_n = 0

    def update(self, n: int = 1) -> None:
        self.n += n
        now = _clock()
        if (self.n - self._last_n >= PROGRESS_LINE_FRACTION * self.total
                and now - self._last_time >= PROGRESS_LINE_S and self.n < self.total):
            self._line(now)

    def _line(self, now: float) -> None:
        elapsed = now - self._start
        rate = self.n / elapsed if elapsed > 0 else 0.0
        left = (f", {_duration((self.total - self.n) / rate)} left"
                if rate > 0 and self.n < self.total else "")
        print(f"{self.desc}: {100 * self.n // max(self.total, 1)}% ({self.n}/{self.total} frames "
              f"in {_duration(elapsed)}, {rate:.2f} frames/s{left})", file=sys.stderr, flush=True)
        self._last_n, self._last_time = self.n, now

    def close(self) -> None:
        if self.n > self._last_n:
            self._line(_clock())


def progress_bar(total: int, desc: str) -> Any:
    """A progress display on stderr for ``total`` frames, with ``update(n=1)`` and
    ``close()``: a bar (frames/s and time left) on a terminal, :class:`ProgressLines`
    elsewhere. The one progress display of every command (render, track, --ray)."""
    if not sys.stderr.isatty():
        return ProgressLines(total, desc)
    from tqdm import tqdm

    return tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
                leave=True, smoothing=0.1,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} frames "
                           "[{elapsed}<{remaining}, {rate_fmt}]")


def say(line: str) -> None:
    """Prints ``line`` on stderr on a line of its own: on a terminal, above a progress bar
    that is showing (which is drawn again below it) instead of after the bar's text."""
    if sys.stderr.isatty():
        from tqdm import tqdm

        tqdm.write(line, file=sys.stderr)
    else:
        print(line, file=sys.stderr, flush=True)


def progress(frames: Iterable[Any], total: int, *, quiet: bool, desc: str) -> Iterator[Any]:
    """``frames`` with a progress display on stderr (:func:`progress_bar`) unless ``quiet``."""
    if quiet or total <= 1:
        yield from frames
        return
    bar = progress_bar(total, desc)
    try:
        for item in frames:
            yield item
            bar.update(1)
    finally:
        bar.close()


def check_layer(scene: str, layer: str | None, names: list[str]) -> None:
    """Refuses a ``--layer`` the scene does not have, naming the scene and its layers."""
    if layer is not None and layer not in names:
        raise InputError(f"{scene}: --layer {layer}: no layer is called that; the layers are {', '.join(names)}")


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


@contextlib.contextmanager
def warnings_as_lines(command: str) -> Iterator[None]:
    """Within: inkwarp's warnings collected, then printed as ``inkwarp COMMAND: warning:``
    lines on stderr once the block has ended (after its progress bars); other warnings go
    on as Python's. Nothing is printed where the block raises."""
    import warnings

    from inkwarp.errors import InkwarpWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InkwarpWarning)
        yield
    for warning in caught:
        if issubclass(warning.category, InkwarpWarning):
            print(f"inkwarp {command}: warning: {warning.message}", file=sys.stderr)
        else:
            warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
