"""Outputs for pipelines: video with alpha (WebM VP9, ProRes 4444 MOV, APNG), sprite sheets
with a TexturePacker JSON, and background overrides (GIF, with 1-bit transparency, is
:mod:`inkwarp.video`'s).

These writers follow :mod:`inkwarp.video`'s rules: frames are RGBA ``uint8`` arrays with
straight alpha, everything is written under a temporary name beside the target and renamed
at the end, and a failure (ffmpeg's included: its exit status is checked) leaves nothing
behind. Video goes through the ffmpeg that the ``imageio-ffmpeg`` wheel ships.

- ``.webm``: VP9 in ``yuva420p`` (alpha kept; plays in browsers, imports into DaVinci
  Resolve, Premiere, After Effects and Blender);
- ``.mov``: Apple ProRes 4444 (``yuva444p10le``; alpha kept, the editing codec);
- ``.apng``: animated PNG, lossless RGBA, looping.

Examples
--------
>>> parse_background("transparent"), parse_background("#ff8000"), parse_background("0,0,0,128")
([0, 0, 0, 0], [255, 128, 0, 255], [0, 0, 0, 128])
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp import video
from inkwarp.errors import InputError
from inkwarp.video import FrameWriter, _temp_name

__all__ = ["ALPHA_KINDS", "SpriteSheetWriter", "open_writer", "parse_background",
           "sheet_layout", "with_background"]

#: Output kinds that keep alpha, by suffix.
ALPHA_KINDS = {".webm": "webm", ".mov": "mov", ".apng": "apng"}

_NAMED = {"white": [255, 255, 255, 255], "black": [0, 0, 0, 255],
          "transparent": [0, 0, 0, 0], "none": [0, 0, 0, 0]}


def parse_background(text: str, option: str = "--background") -> list[int]:
    """An RGBA background from ``transparent``, ``white``, ``black``, ``#RRGGBB``,
    ``#RRGGBBAA`` or ``R,G,B[,A]`` (0-255); a message names ``option`` (``"background"``
    for Python's argument)."""
    from inkwarp.cli._common import given

    spec = text.strip().lower()
    if spec in _NAMED:
        return list(_NAMED[spec])
    if spec.startswith("#") and len(spec) in (7, 9):
        try:
            values = [int(spec[i:i + 2], 16) for i in range(1, len(spec), 2)]
        except ValueError:
            values = []
        if values:
            return values + [255] * (4 - len(values))
    parts = [p.strip() for p in spec.split(",")]
    if len(parts) in (3, 4) and all(p.isdigit() and int(p) <= 255 for p in parts):
        return [int(p) for p in parts] + [255] * (4 - len(parts))
    raise InputError(f"{given(option, text if spec else repr(text))}: give transparent, white, black, #RRGGBB, "
                     "#RRGGBBAA or R,G,B[,A] with numbers 0-255")


def with_background(scene: Any, background: list[int]) -> Any:
    """The same scene with another background colour (images are not read again from a
    different place: paths stay relative to the scene's folder)."""
    from inkwarp.scene import Scene

    data = scene.to_dict()
    data["background"] = list(background)
    out = Scene.from_dict(data, base_dir=scene.base_dir)
    out.file = scene.file
    return out


def _ffmpeg() -> str:
    import imageio_ffmpeg

    return imageio_ffmpeg.get_ffmpeg_exe()


class FfmpegAlphaWriter(FrameWriter):
    """RGBA frames streamed to ffmpeg, encoded with alpha (see the module's list)."""

    CODECS = {
        "webm": ["-c:v", "libvpx-vp9", "-pix_fmt", "yuva420p", "-crf", "18", "-b:v", "0",
                 "-row-mt", "1", "-auto-alt-ref", "0", "-f", "webm"],
        "mov": ["-c:v", "prores_ks", "-profile:v", "4444", "-pix_fmt", "yuva444p10le",
                "-alpha_bits", "16", "-vendor", "apl0", "-f", "mov"],
        "apng": ["-c:v", "apng", "-pix_fmt", "rgba", "-plays", "0", "-f", "apng"],
    }

    def __init__(self, target: Path, fps: float, kind: str) -> None:
        super().__init__(target, fps)
        self.kind = kind
        self._temp: Path | None = None
        self._process: subprocess.Popen[bytes] | None = None
        self._log: Any = None

    def _start(self, width: int, height: int) -> None:
        self._temp = _temp_name(self.target, self.target.suffix)
        self._log = tempfile.TemporaryFile()
        command = [_ffmpeg(), "-hide_banner", "-loglevel", "error", "-y",
                   "-f", "rawvideo", "-pix_fmt", "rgba", "-s", f"{width}x{height}",
                   "-r", video.ffmpeg_rate(self.fps), "-i", "-", *([] if self.kind == "apng" else video.BT709),
                   *self.CODECS[self.kind], str(self._temp)]
        self._process = subprocess.Popen(command, stdin=subprocess.PIPE,
                                         stdout=subprocess.DEVNULL, stderr=self._log)

    def _write(self, frame: np.ndarray) -> None:
        rgba = frame if frame.shape[2] == 4 else np.dstack(
            [frame, np.full(frame.shape[:2], 255, np.uint8)])
        if self._process is None:
            self._start(rgba.shape[1], rgba.shape[0])
        assert self._process is not None and self._process.stdin is not None
        try:
            self._process.stdin.write(np.ascontiguousarray(rgba).tobytes())
        except BrokenPipeError:
            # ffmpeg stopped reading: its exit status and messages say why.
            raise video.ffmpeg_failure(self.target, self._process.wait(), self._errors()
                                       ) from None

    def _errors(self) -> str:
        if self._log is None:
            return ""
        self._log.seek(0)
        return self._log.read().decode("utf-8", "replace").strip()

    def _commit(self) -> list[Path]:
        assert self._process is not None and self._process.stdin is not None
        try:
            self._process.stdin.close()
        except BrokenPipeError:
            pass  # ffmpeg stopped: its exit status says why
        code = self._process.wait()
        if code != 0:
            raise video.ffmpeg_failure(self.target, code, self._errors())
        self._process = None
        assert self._temp is not None
        os.replace(self._temp, self.target)
        self._log.close()
        return [self.target]

    def _discard(self) -> None:
        if self._process is not None:
            if self._process.stdin is not None:
                try:
                    self._process.stdin.close()
                except OSError:
                    pass
            self._process.kill()
            self._process.wait()
            self._process = None
        if self._log is not None:
            self._log.close()
        if self._temp is not None:
            self._temp.unlink(missing_ok=True)


#: The widest side of a sprite sheet: the largest texture Unity, Godot and WebGL engines load
#: (and TexturePacker makes); a bigger atlas would also have to be held whole in memory.
MAX_SHEET_SIDE_PX = 16384


def check_sheet_size(columns: int, rows: int, width: int, height: int, spec: str | None,
                     option: str = "--sprite-sheet") -> None:
    """Refuse, before any rendering, a sprite sheet wider or taller than
    :data:`MAX_SHEET_SIDE_PX`; the message names ``option`` (``"sprite_sheet"`` for
    Python's argument)."""
    from inkwarp.cli._common import given

    w, h = columns * width, rows * height
    if max(w, h) > MAX_SHEET_SIDE_PX:
        cli = option.startswith("-")
        if spec and spec != "auto":
            what = given(option, spec)
        else:
            what = option if cli else f"{option}=True"
        frames = "--frames" if cli else "frames=(A, B)"
        raise InputError(f"{what}: {columns}x{rows} frames of {width}x{height} make a "
                         f"{w}x{h} sheet, over the {MAX_SHEET_SIDE_PX} px a side that game "
                         f"engines load; pick fewer frames with {frames}, another COLSxROWS, "
                         "or render a smaller scene")


def check_sheet_json(target: str | os.PathLike[str], scene_path: str | os.PathLike[str] | None) -> None:
    """Refuse a sprite sheet whose ``.json`` beside the atlas would replace the scene being
    rendered (``-o character.png`` for ``character.json``), before any rendering."""
    out = Path(os.fspath(target))
    sheet_json = out.with_suffix(".json")
    if scene_path is not None and sheet_json.exists() and os.path.exists(scene_path) and os.path.samefile(sheet_json, scene_path):
        raise InputError(f"{target}: the sprite sheet's {sheet_json.name} would replace the "
                         f"scene {scene_path}; name the sheet otherwise, such as "
                         f"{sheet_json.stem}-sheet.png")
    # Another scene, or any JSON that is not an earlier sheet's atlas, is not replaced either.
    check_ours(sheet_json, lambda doc: "meta" in doc, "sheet's atlas", f"{target}: the sprite sheet's {sheet_json.name}",
               f"{out.stem}-sheet{out.suffix}")


def _scene_inputs(scene: Any) -> tuple[Path | None, list[Path]]:
    """The scene's own file (None for one built from a dict) and every file it reads: that
    file and its layers' ``image``, ``alpha`` and ``continuity`` pictures. ``scene`` is a
    scene file's path or a loaded :class:`~inkwarp.Scene` (its pictures as it holds them,
    relative to its ``base_dir``)."""
    import json

    if isinstance(scene, (str, os.PathLike)):
        own: Path | None = Path(os.fspath(scene))
        base = own.parent
        try:
            doc = json.loads(own.read_text(encoding="utf-8-sig"))
        except (OSError, ValueError):
            doc = {}  # the scene itself is checked, with a clear error, when it is loaded
    else:
        own = Path(scene.file) if getattr(scene, "file", None) else None
        base = Path(scene.base_dir) if getattr(scene, "base_dir", None) else Path.cwd()
        doc = scene.to_dict()
    inputs = [own] if own is not None else []
    layers = doc.get("layers", []) if isinstance(doc, dict) else []
    for layer in layers if isinstance(layers, list) else []:
        for key in ("image", "alpha", "continuity"):
            ref = layer.get(key) if isinstance(layer, dict) else None
            if isinstance(ref, str) and not ref.startswith("data:"):
                inputs.append(base / ref)
    return own, inputs


def check_not_an_input(target: str | os.PathLike[str], scene: Any, written: str = "frame") -> None:
    """Refuse an output that is one of the scene's own files (the scene, or a layer's
    ``image``, ``alpha`` or ``continuity`` picture), before any rendering: ``-o face.png``
    beside a layer drawn from ``face.png`` would replace the artwork with a frame (or the
    ``written`` output of another command). ``scene``: a scene file's path or a Scene."""
    out = Path(os.fspath(target))
    if not out.exists():
        return
    own, inputs = _scene_inputs(scene)
    for path in inputs:
        if path.exists() and os.path.samefile(out, path):
            what = "the scene" if path == own else "an image of the scene"
            raise InputError(f"{target}: is {what} being rendered ({path}); writing the {written} "
                             f"there would replace it. Name the output otherwise, such as "
                             f"{out.stem}-{written.split()[-1]}{out.suffix}")


def check_frames_not_inputs(folder: str | os.PathLike[str], first: int, stop: int, scene: Any) -> None:
    """Refuse a render into ``folder`` whose frame files ``first`` to ``stop - 1``
    (``frame_NNNN.png``) would replace one of the scene's own files: a picture named like a
    frame, rendered into its own folder (on a file system that ignores case, whatever the
    case of its name). ``scene``: a scene file's path or a Scene."""
    import re

    from inkwarp.video import FRAME_PATTERN

    out = Path(os.fspath(folder))
    if not out.is_dir():
        return
    for path in _scene_inputs(scene)[1]:
        named = re.fullmatch(r"frame_(\d+)\.png", path.name, re.IGNORECASE)
        index = int(named.group(1)) if named else -1
        if not first <= index < stop:
            continue
        frame = out / FRAME_PATTERN.format(index)
        if path.exists() and frame.exists() and os.path.samefile(frame, path):
            raise InputError(f"{folder}: frame {index} would be written over {path}, an "
                             f"image of the scene being rendered. Render into another folder, such "
                             f"as {out / 'frames'}/")


def check_not_the_input(target: str | os.PathLike[str], given: str | os.PathLike[str], option: str,
                        suffix: str) -> None:
    """Refuse, before any work, an output that is the input file ``given`` (as ``option``):
    writing it would replace that file."""
    out = Path(os.fspath(target))
    if out.exists() and os.path.exists(given) and os.path.samefile(out, given):
        raise InputError(f"{out}: is the input ({option} {given}); writing there would replace "
                         f"it. Name the output otherwise, such as {out.stem}{suffix}{out.suffix}")


def check_ours(target: str | os.PathLike[str], ours: Callable[[dict[str, Any]], bool], written: str,
               lead: str | None = None, instead: str | None = None) -> None:
    """Refuse, before any work, to replace an existing file unless it is a JSON object that
    ``ours`` takes for an earlier output of the command (a sprite sheet's atlas, the schema):
    a scene, or any other file, is the user's."""
    out = Path(os.fspath(target))
    if not out.is_file():
        return
    try:
        doc = json.loads(out.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        doc = None
    if isinstance(doc, dict) and ours(doc):
        return
    what = "a scene" if isinstance(doc, dict) and "layers" in doc else "a file inkwarp did not write"
    raise InputError(f"{lead or str(target) + ':'} is {what}; writing the {written} there would replace it. "
                     f"Name it otherwise, such as {instead or out.stem + '-' + written + out.suffix}, or "
                     "remove the file first")


def sheet_layout(count: int, spec: str | None, option: str = "--sprite-sheet",
                 size: tuple[int, int] | None = None) -> tuple[int, int]:
    """``(columns, rows)`` of a sprite sheet for ``count`` frames: ``COLSxROWS``, ``COLS``
    (rows as needed), or None for the squarest grid (of frames ``size = (width, height)``
    where given: the sheet whose longer side is shortest, so the most frames fit the
    engines' limit); a message names ``option`` (``"sprite_sheet"`` for Python's argument).

    Examples
    --------
    >>> sheet_layout(10, None), sheet_layout(10, "5"), sheet_layout(10, "2x5")
    ((4, 3), (5, 2), (2, 5))
    >>> sheet_layout(1440, None, size=(451, 300))  # 38x38 made a sheet 17138 px wide
    (31, 47)
    """
    if spec is None or spec == "auto":
        if size is not None and count > 0:
            width, height = size
            side = lambda c: max(c * width, math.ceil(count / c) * height)  # noqa: E731
            columns = min(range(1, count + 1), key=lambda c: (side(c), c * math.ceil(count / c), -c))
            return columns, math.ceil(count / columns)
        columns = max(1, math.ceil(math.sqrt(count)))
        return columns, max(1, math.ceil(count / columns))
    from inkwarp.cli._common import given

    text = spec.lower().strip()
    try:
        if "x" in text:
            c, r = (int(v) for v in text.split("x", 1))
        else:
            c = int(text)
            r = math.ceil(count / c) if c > 0 else 0
    except ValueError:
        raise InputError(f"{given(option, spec)}: give COLSxROWS (such as 8x4) or COLS"
                         ) from None
    if c < 1 or r < 1:
        raise InputError(f"{given(option, spec)}: columns and rows must be at least 1")
    if c * r < count:
        raise InputError(f"{given(option, spec)}: {c}x{r} holds {_frames(c * r)}, the render "
                         f"has {count}; give more rows or columns, or pick fewer with "
                         f"{'--frames' if option.startswith('-') else 'frames=(A, B)'}")
    return c, r


def _frames(n: int) -> str:
    return f"{n} frame{'' if n == 1 else 's'}"


class SpriteSheetWriter(FrameWriter):
    """Frames on one PNG atlas, left to right then top to bottom, with a JSON beside it in
    TexturePacker's "hash" layout (``frames`` by name, each with ``frame``, ``rotated``,
    ``trimmed``, ``spriteSourceSize``, ``sourceSize`` and ``duration`` in milliseconds;
    ``meta`` with ``image``, ``size``, ``scale``, ``format``), which Phaser, PixiJS, Godot
    and Unity importers read. Frame names are ``frame_NNNN.png``, numbered from
    ``first_frame``."""

    def __init__(self, target: Path, fps: float, count: int, layout: str | None = None,
                 first_frame: int = 0, size: tuple[int, int] | None = None) -> None:
        super().__init__(target, fps)
        self.count = count
        self.columns, self.rows = sheet_layout(count, layout, size=size)
        self.first_frame = first_frame
        self.json_path = target.with_suffix(".json")
        self._sheet: np.ndarray | None = None
        self._temps: list[Path] = []

    def _write(self, frame: np.ndarray) -> None:
        if self.frames_written >= self.columns * self.rows:
            raise InputError(f"{self.target}: the sheet holds {_frames(self.columns * self.rows)}")
        h, w = frame.shape[:2]
        if self._sheet is None:
            self._sheet = np.zeros((h * self.rows, w * self.columns, 4), np.uint8)
        rgba = frame if frame.shape[2] == 4 else np.dstack([frame, np.full((h, w), 255, np.uint8)])
        row, column = divmod(self.frames_written, self.columns)
        self._sheet[row * h:(row + 1) * h, column * w:(column + 1) * w] = rgba

    def frame_json(self) -> dict[str, Any]:
        from inkwarp import __version__

        assert self.size is not None
        w, h = self.size
        n = self.frames_written
        ends = [round((i + 1) * 1000 / self.fps) for i in range(n)]
        starts = [0] + ends[:-1]
        frames = {}
        for i in range(n):
            row, column = divmod(i, self.columns)
            frames[video.FRAME_PATTERN.format(self.first_frame + i)] = {
                "frame": {"x": column * w, "y": row * h, "w": w, "h": h},
                "rotated": False, "trimmed": False,
                "spriteSourceSize": {"x": 0, "y": 0, "w": w, "h": h},
                "sourceSize": {"w": w, "h": h},
                "duration": ends[i] - starts[i],
            }
        return {"frames": frames,
                "meta": {"app": "inkwarp", "version": __version__, "image": self.target.name,
                         "format": "RGBA8888",
                         "size": {"w": w * self.columns, "h": h * self.rows}, "scale": "1",
                         "fps": self.fps}}

    def _commit(self) -> list[Path]:
        from PIL import Image

        from inkwarp.imaging import PNG_COMPRESS_LEVEL

        assert self._sheet is not None
        image_temp = _temp_name(self.target, ".png")
        json_temp = _temp_name(self.json_path, ".json")
        self._temps = [image_temp, json_temp]
        Image.fromarray(self._sheet, "RGBA").save(image_temp, format="PNG", compress_level=PNG_COMPRESS_LEVEL)
        json_temp.write_text(json.dumps(self.frame_json(), indent=2) + "\n", encoding="utf-8")
        os.replace(image_temp, self.target)
        os.replace(json_temp, self.json_path)
        self._sheet = None
        return [self.target, self.json_path]

    def _discard(self) -> None:
        self._sheet = None
        for temp in self._temps:
            temp.unlink(missing_ok=True)


def open_writer(path: str | os.PathLike[str], *, fps: float, kind: str | None = None,
                first_frame: int = 0, frames: int = 1) -> FrameWriter:
    """The writer for ``path``: the alpha formats here, otherwise
    :func:`inkwarp.video.open_writer`."""
    kind = kind or video.output_kind(path)
    target = video.check_target(path, kind)  # type: ignore[arg-type]
    if kind in ALPHA_KINDS.values():
        return FfmpegAlphaWriter(target, fps, kind)
    return video.open_writer(target, fps=fps, kind=kind, first_frame=first_frame, frames=frames)  # type: ignore[arg-type]
