"""Scenes: images in layers, a drawing traced over them, and keys that move it over time.

A scene is one JSON file (the format is described in ``docs/reference/scene-format.md`` and
by :func:`scene_schema`). :class:`Scene` reads one, checks it (every problem is reported at
once, each with its JSON path, as :class:`inkwarp.SceneError`) and renders it with the
compiled engine: single frames, displacement fields, or the whole animation, each frame
warm-started from the one before.

Example
-------
>>> import numpy as np
>>> import inkwarp
>>> art = np.zeros((48, 64, 4), np.uint8)
>>> art[8:40, 16:48] = (255, 128, 0, 255)                  # an orange square
>>> scene = inkwarp.Scene.from_dict({
...     "inkwarp": 1, "fps": 12, "duration": 1.0,
...     "layers": [{"name": "square", "image": inkwarp.image_data_uri(art)}],
...     "features": [{"id": "corner", "kind": "point", "rest": [[16, 8]],
...                   "keys": [{"t": 0, "points": [[16, 8]]},
...                            {"t": 1, "points": [[20, 8]]}]}]})
>>> scene.width, scene.height, scene.frame_count
(64, 48, 12)
>>> scene.render(time=0.0).shape
(48, 64, 4)
>>> scene.field(time=1.0)[8, 16]                           # (dx, dy) at x=16, y=8
array([4., 0.], dtype=float32)
>>> len([frame for frame in scene.frames()])
12
"""

from __future__ import annotations

import base64
import io
import json
import math
import os
import stat
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp import _inkwarp
from inkwarp.drawing import off_picture
from inkwarp.errors import InputError, MissingFileError, SceneError

__all__ = ["WARM_CHAIN_FRAMES", "Frames", "Scene", "image_data_uri", "preroll_start", "scene_schema",
           "validate_scene"]

#: One problem of a scene: ``(JSON path, message)``.
Problem = tuple[str, str]


def scene_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of the scene format, generated from the engine's types.

    Returns
    -------
    dict
        The schema; ``json.dumps(scene_schema(), indent=2)`` is what ``inkwarp schema``
        prints.

    Examples
    --------
    >>> import inkwarp
    >>> schema = inkwarp.scene_schema()
    >>> schema["properties"]["inkwarp"]["const"]
    1
    >>> sorted(schema["required"])
    ['inkwarp', 'layers']
    """
    return json.loads(_inkwarp.scene_schema())


def image_data_uri(image: np.ndarray) -> str:
    """Encodes an image array as a ``data:image/png;base64,...`` URI for a scene's layers.

    Parameters
    ----------
    image : ndarray
        uint8 ``(H, W, 4)`` RGBA (straight alpha), ``(H, W, 3)`` RGB or ``(H, W)`` grey.

    Returns
    -------
    str
        A PNG data URI, usable wherever a scene takes an image path.

    Examples
    --------
    >>> import numpy as np
    >>> image_data_uri(np.zeros((2, 2, 4), np.uint8))[:22]
    'data:image/png;base64,'
    """
    from PIL import Image

    array = np.asarray(image)
    if array.dtype != np.uint8 or array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[2] not in (3, 4)):
        raise InputError(
            f"expected a uint8 image of shape (H, W), (H, W, 3) or (H, W, 4), got {array.dtype} {array.shape}"
        )
    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(array)).save(buffer, format="PNG")
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


#: No scene nests deeper than a handful of levels; a dict deeper than this is refused
#: (as a problem, not a RecursionError).
MAX_DEPTH = 64


def _plain(value: Any, path: str, problems: list[Problem], depth: int = 0) -> Any:
    """``value`` as plain JSON data (NumPy arrays and scalars converted); non-finite numbers
    and values JSON cannot hold become problems (and placeholders, so that checking goes on)."""
    if depth > MAX_DEPTH and isinstance(value, (Mapping, np.ndarray, list, tuple)):
        problems.append((path, f"nested more than {MAX_DEPTH} levels deep; a scene never is"))
        return None
    if isinstance(value, Mapping):
        return {str(k): _plain(v, _join(path, str(k)), problems, depth + 1) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(v, f"{path}[{i}]", problems, depth + 1) for i, v in enumerate(value)]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        if not math.isfinite(number):
            problems.append((path, f"numbers must be finite, found {number}; use a finite number"))
            return 0.0
        return number
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if value is None or isinstance(value, str):
        return value
    problems.append(
        (path, f"a {type(value).__name__} cannot be stored in a scene; use numbers, strings, lists and dicts")
    )
    return None


def _raise_for(problems: list[Problem], file: str | None) -> None:
    if not problems:
        return
    if len(problems) == 1:
        path, message = problems[0]
        text = f"{path}: {message}" if path else message
    else:
        lines = [f"{p}: {m}" if p else m for p, m in problems]
        text = f"{len(problems)} problems:\n  " + "\n  ".join(lines)
    raise SceneError(f"{file}: {text}" if file else text, file=file, path=problems[0][0], problems=problems)


def _dict_to_json(data: Mapping[str, Any]) -> tuple[str, list[Problem]]:
    if not isinstance(data, Mapping):
        raise SceneError(
            f"a scene is a dict such as {{'inkwarp': 1, 'layers': [...]}}, got {type(data).__name__}",
            path="",
        )
    problems: list[Problem] = []
    plain = _plain(data, "", problems)
    return json.dumps(plain), problems


class _Object(dict):  # type: ignore[type-arg]
    """A JSON object as parsed, with the keys it held more than once."""

    repeated: list[str]


def _object(pairs: list[tuple[str, Any]]) -> _Object:
    obj = _Object(pairs)
    seen: set[str] = set()
    obj.repeated = [k for k, _ in pairs if k in seen or seen.add(k)]  # type: ignore[func-returns-value]
    return obj


def _repeated_keys(text: str) -> list[Problem]:
    """A problem for every key that stands twice in one object of the scene's JSON ``text``
    (JSON parsers keep one of them silently, so a hand edit could be lost); none for text
    that is not JSON (the engine says why)."""
    try:
        doc = json.loads(text, object_pairs_hook=_object)
    except (ValueError, RecursionError):
        return []
    problems: list[Problem] = []

    def walk(v: Any, path: str) -> None:
        if isinstance(v, _Object):
            at = (lambda key: f"{path}.{key}" if path else key)
            problems.extend((at(key), "given more than once in its object; keep one (JSON takes each key "
                                      "once: the last would win)") for key in dict.fromkeys(v.repeated))
            for key, item in v.items():
                walk(item, at(key))
        elif isinstance(v, list):
            for i, item in enumerate(v):
                walk(item, f"{path}[{i}]")

    walk(doc, "")
    return problems


def validate_scene(source: str | os.PathLike[str] | Mapping[str, Any], base_dir: str | os.PathLike[str] | None = None) -> list[Problem]:
    """Every problem of a scene, images included, without raising.

    Parameters
    ----------
    source : path or dict
        A scene file, or a scene as a dict.
    base_dir : path, optional
        Folder that image paths of a dict are relative to (default: the current folder; a
        file's own folder for a file).

    Returns
    -------
    list of (str, str)
        ``(JSON path, message)`` for each problem; empty when the scene is valid.

    Examples
    --------
    >>> validate_scene({"inkwarp": 1, "fps": 0, "width": 8, "height": 8,
    ...                 "layers": [{"name": "main"}]})
    [('fps', 'frames per second must be a number from 0.001 (one frame every 1000 s) to 1000, found 0.0; use e.g. 24')]
    """
    if isinstance(source, Mapping):
        text, problems = _dict_to_json(source)
        base = os.fspath(base_dir) if base_dir is not None else None
    else:
        path = Path(_path_argument(source, "source (a scene file or dict)"))
        try:
            text = read_scene_text(path)
        except FileNotFoundError:
            return [("", f"no such scene file: {path}")]
        except SceneError as err:
            return [("", str(err).removeprefix(f"{path}: "))]
        except OSError as err:
            return [("", f"cannot read the scene file {path}: {err.strerror or err}")]
        problems = _repeated_keys(text)
        base = os.fspath(base_dir) if base_dir is not None else os.fspath(path.resolve().parent)
    return problems + [p for p in _inkwarp.scene_problems(text, base) if p[0] not in {q[0] for q in problems}]


#: The largest scene file read (images inline as data: URIs count).
MAX_SCENE_FILE_BYTES = 1 << 30


def read_scene_text(file: str | os.PathLike[str]) -> str:
    """A scene file's text: UTF-8, with or without a byte-order mark.

    Raises
    ------
    inkwarp.errors.MissingFileError
        When there is no such file.
    inkwarp.SceneError
        When it is not a regular file (a FIFO or a device such as /dev/zero would block or
        never end), is too large, empty, or not UTF-8 text.
    """
    name = os.fspath(file)
    try:
        info = os.stat(name)
    except FileNotFoundError as err:
        raise MissingFileError(err.errno, err.strerror, name) from None
    if not stat.S_ISREG(info.st_mode):
        raise SceneError(f"{name}: not a regular file (a folder, FIFO or device); give a scene's "
                         "JSON file", file=name)
    if info.st_size > MAX_SCENE_FILE_BYTES:
        raise SceneError(f"{name}: {info.st_size >> 20} MiB is more than the "
                         f"{MAX_SCENE_FILE_BYTES >> 20} MiB a scene file may have; keep pictures "
                         "as files beside it", file=name)
    data = Path(name).read_bytes()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        picture = _picture_kind(data)
        if picture:
            raise SceneError(f"{name}: a {picture} picture, not a scene; make a scene of it with "
                             f"inkwarp new {name} -o scene.json", file=name) from None
        video = _video_kind(data)
        if video:
            raise SceneError(f"{name}: {'an' if video in ('MP4', 'AVI') else 'a'} {video} video, not a scene; "
                             f"a scene is a JSON file (inkwarp new PICTURE -o scene.json), and inkwarp track "
                             f"{name} --scene SCENE follows its drawing through the video", file=name) from None
        line = data[: err.start].count(b"\n") + 1
        raise SceneError(f"{name}: not UTF-8 text (byte {err.start}, line {line}); save the "
                         "scene as UTF-8", file=name) from None
    if not text.strip():
        raise SceneError(f"{name}: the file is empty (a save that did not finish?); write the scene "
                         f"again, or make one over it with inkwarp new PICTURE -o {name} --force", file=name)
    if text.lstrip().startswith("<") and "<svg" in text[:4096]:
        raise SceneError(f"{name}: an SVG drawing, not a scene; trace it over its picture into a "
                         f"scene with inkwarp new PICTURE --drawing {name} -o scene.json", file=name)
    return text


def _core_from_json(text: str, base: str | None, file: str | None) -> Any:
    """The engine's scene of JSON ``text``; where the text is JSON to Python but not to the
    engine, the error says why: it holds NaN or Infinity, which JSON has no numbers for."""
    repeated = _repeated_keys(text)
    if repeated:
        others = _inkwarp.scene_problems(text, base)
        _raise_for(repeated + [p for p in others if p[0] not in {q[0] for q in repeated}], file)
    try:
        return _inkwarp.SceneCore.from_json(text, base, file)
    except SceneError as err:
        if "not valid JSON" not in str(err) or ("NaN" not in text and "Infinity" not in text):
            raise
        try:
            json.loads(text)
        except (ValueError, RecursionError):
            raise err from None
        raise SceneError(f"{err}; NaN and Infinity are not JSON numbers: write a finite number "
                         "there", file=err.file, path=err.path) from None


def _picture_kind(data: bytes) -> str | None:
    """The kind of picture ``data`` starts as (PNG, JPEG, GIF, WebP, PSD, TIFF, HEIC, AVIF), or None."""
    kinds = {b"\x89PNG": "PNG", b"\xff\xd8\xff": "JPEG", b"GIF8": "GIF", b"8BPS": "PSD",
             b"II*\x00": "TIFF", b"MM\x00*": "TIFF"}
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "WebP"
    if data[4:8] == b"ftyp" and data[8:12] in (b"heic", b"heix", b"mif1", b"msf1", b"avif", b"avis"):
        return "AVIF" if data[8:12] in (b"avif", b"avis") else "HEIC"
    return next((kind for magic, kind in kinds.items() if data.startswith(magic)), None)


def _video_kind(data: bytes) -> str | None:
    """The kind of video ``data`` starts as (MP4, MOV, WebM, Matroska, AVI), or None, by the
    engine's rule (a HEIC or AVIF picture is not one)."""
    return _inkwarp.video_kind(data)


#: The engine's warm-start chain length (``WARM_CHAIN_FRAMES`` in the core's scene engine):
#: frames 0, 16, 32, ... are solved from zero, every other frame from the ones before it.
WARM_CHAIN_FRAMES = 16


def preroll_start(start: int) -> int:
    """The frame a range starting at ``start`` must be solved from to match a sequential
    render: the start of its warm-start chain.

    Examples
    --------
    >>> preroll_start(37), preroll_start(32)
    (32, 32)
    """
    return (start // WARM_CHAIN_FRAMES) * WARM_CHAIN_FRAMES


class Frames(Iterator[np.ndarray]):
    """The frames of a scene, in order, as RGBA uint8 arrays ``(H, W, 4)``.

    Rendered by the engine while you consume them (on worker threads, at most a few frames
    ahead, when more than one thread renders). ``len()`` gives the number of frames still
    to come; ``close()`` (or leaving a ``with`` block) stops the rendering early.
    :attr:`index` is the frame number of the frame last returned.

    The engine's frames start at ``start - preroll``: the first ``preroll`` (the pre-roll
    of a range that starts inside a warm-start chain) are solved and dropped before the
    first frame is returned, and so are their convergence warnings, which are about frames
    not returned.
    """

    def __init__(self, core: Any, start: int, preroll: int = 0) -> None:
        self._core = core
        self.index = start - 1
        self._preroll = preroll

    def __iter__(self) -> Frames:
        return self

    def _drop_preroll(self) -> None:
        import warnings

        from inkwarp.errors import ConvergenceWarning

        while self._preroll > 0:
            self._preroll -= 1
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ConvergenceWarning)
                if self._core.__next__() is None:
                    self._preroll = 0

    def __next__(self) -> np.ndarray:
        if self._preroll:
            self._drop_preroll()
        item = self._core.__next__()
        if item is None:
            raise StopIteration
        self.index, frame = item
        return frame

    def __len__(self) -> int:
        return max(0, len(self._core) - self._preroll)

    def close(self) -> None:
        """Stops rendering; the iterator is exhausted afterwards."""
        self._core.close()

    def __enter__(self) -> Frames:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()



def _path_argument(path: Any, what: str) -> str:
    """``path`` as a string, or a ValueError naming what was given instead."""
    if isinstance(path, (str, os.PathLike)):
        text = os.fspath(path)
        if isinstance(text, str):
            return text
    raise InputError(f"{what} must be a path (str or os.PathLike); got {type(path).__name__}")


def _method_argument(method: Any) -> str | None:
    """``method`` if it is None or a string (the engine names an unknown one), else a
    ValueError naming the methods."""
    from inkwarp.methods import METHODS

    if method is not None and not isinstance(method, str):
        raise InputError(f"method must be one of {', '.join(map(repr, METHODS))} (or None for each layer's "
                         f"solver.method); got {method!r}")
    return method


def _integer_argument(value: Any, name: str) -> int:
    """``value`` as an int, or a ValueError naming the argument."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer():
            return int(value)
        raise InputError(f"{name} must be a whole number; got {value!r:.40}")
    return int(value)


def _number_argument(value: Any, name: str) -> float:
    """``value`` as a finite float, or a ValueError naming the argument."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be a number; got {type(value).__name__} {value!r:.40}")
    try:
        number = float(value)
    except OverflowError:
        raise InputError(f"{name} must be a finite number; got {value!r:.40}") from None
    if not math.isfinite(number):
        raise InputError(f"{name} must be a finite number; got {value!r:.40}")
    return number

def _check_finite_field(field: Any, where: str) -> None:
    """A field with a NaN or an infinity would render as a blank frame: refuse it instead."""
    values = np.asarray(field)
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        bad = int(values.size - np.count_nonzero(np.isfinite(values)))
        raise InputError(
            f"the displacement field of {where} is not finite ({bad} of {values.size} values): "
            "the keys around this time or the solver settings overflow; move keys that are "
            "almost at the same time apart, or lower solver.tension / beier_neely weights")


def _rebuilt_scene(cls: type[Scene], text: str, base_dir: str | None, file: str | None) -> Scene:
    """A pickled or copied :class:`Scene`, built again from its document (``Scene.__reduce__``)."""
    return cls(_core_from_json(text, base_dir, file), file=file, base_dir=base_dir)


class Scene:
    """A scene ready to render: its layers' images decoded, mattes and cuts applied.

    Build one with :meth:`load` (a file) or :meth:`from_dict`. Both check the whole scene
    first and raise :class:`inkwarp.SceneError` listing every problem (``.problems``), the
    first one's JSON path (``.path``) and the file (``.file``).

    Times are in seconds; frame ``i`` is at time ``i / fps``. Before a feature's first key
    it holds that key, after its last key the last one.

    A scene can be pickled (to a process pool, say) and copied with :func:`copy.deepcopy`:
    the copy is built again from its document (:meth:`to_dict`) and folder (``base_dir``),
    so it renders the same frames. Images held as ``data:`` URIs travel with it; image
    files are read again where it is unpickled, so they must be there (on another machine,
    pickle a scene whose images are ``data:`` URIs, as :meth:`new` makes them).
    """

    def __init__(self, core: Any, *, file: str | None = None, base_dir: str | None = None) -> None:
        """Wraps a resolved engine scene; use :meth:`load` or :meth:`from_dict` instead."""
        self._core = core
        self.file = file
        self.base_dir = base_dir

    def __reduce__(self) -> tuple[Any, ...]:
        # The engine's scene cannot be pickled; its document and folder rebuild it (images
        # read again from the same absolute folder, whatever the current one is then).
        state = {key: value for key, value in self.__dict__.items() if key != "_core"}
        return _rebuilt_scene, (type(self), self._core.doc_json(), self.base_dir, self.file), state

    # ---- construction -------------------------------------------------------------------

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scene:
        """Reads a scene file; image paths in it are relative to its folder.

        Parameters
        ----------
        path : path
            The scene's JSON file.

        Raises
        ------
        inkwarp.errors.MissingFileError
            When there is no such file.
        inkwarp.SceneError
            When the scene has problems (all of them are listed).
        """
        file = _path_argument(path, "Scene.load's path")
        text = read_scene_text(file)
        base_dir = os.fspath(Path(file).resolve().parent)
        return cls(_core_from_json(text, base_dir, file), file=file, base_dir=base_dir)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: str | os.PathLike[str] | None = None) -> Scene:
        """Builds a scene from a dict in the scene format (NumPy arrays allowed for points).

        Parameters
        ----------
        data : dict
            The scene, as :func:`json.load` would return it.
        base_dir : path, optional
            Folder that image paths are relative to (default: the current folder).

        Raises
        ------
        inkwarp.SceneError
            When the scene has problems (all of them are listed).

        Examples
        --------
        >>> Scene.from_dict({"inkwarp": 1, "width": 4, "height": 3,
        ...                  "layers": [{"name": "main"}]}).render().shape
        (3, 4, 4)
        """
        text, problems = _dict_to_json(data)
        base = _path_argument(base_dir, "base_dir") if base_dir is not None else None
        if problems:
            others = _inkwarp.scene_problems(text, base)
            _raise_for(problems + [p for p in others if p[0] not in {q[0] for q in problems}], None)
        # Kept as the folder it was when the images were read, so that save() elsewhere
        # rewrites their relative paths from there.
        return cls(_core_from_json(text, base, None), base_dir=os.path.abspath(base if base is not None else os.curdir))

    @classmethod
    def new(cls, picture: str | os.PathLike[str], *, drawing: str | os.PathLike[str] | None = None,
            fps: float = 24.0, duration: float = 2.0) -> Scene:
        """A new scene started from a picture: one layer for a PNG, JPEG or WebP, one layer
        per pixel layer for a layered PSD (see :mod:`inkwarp.importing`), and the features
        of an SVG ``drawing`` traced over it (see :mod:`inkwarp.svg`).

        The layers' images are held as ``data:`` URIs; :meth:`save` writes the scene as
        one file (``inkwarp new`` writes the images beside it instead). The background is
        transparent, and every layer holds its border (``"border": "hold"``, as a picture
        opened in the editor does). Notes about the picture (flattened groups, blend modes other than
        Normal) are issued as :class:`inkwarp.InkwarpWarning`.
        """
        from inkwarp.importing import new_scene

        picture = _path_argument(picture, "picture")
        drawing = _path_argument(drawing, "drawing") if drawing is not None else None
        return cls.from_dict(new_scene(picture, drawing=drawing, fps=fps, duration=duration))

    @classmethod
    def from_json(cls, text: str, base_dir: str | os.PathLike[str] | None = None) -> Scene:
        """Builds a scene from JSON text, ``str`` or UTF-8 ``bytes`` (see :meth:`from_dict`)."""
        if isinstance(text, (bytes, bytearray)):
            try:
                text = bytes(text).decode("utf-8-sig")
            except UnicodeDecodeError as err:
                raise SceneError(f"the scene's bytes are not UTF-8 text ({err}); save the scene as UTF-8") from None
        if not isinstance(text, str):
            raise InputError(f"text must be the scene's JSON text (str or bytes); got {type(text).__name__}")
        base = _path_argument(base_dir, "base_dir") if base_dir is not None else None
        return cls(_core_from_json(text, base, None), base_dir=os.path.abspath(base if base is not None else os.curdir))

    # ---- what it is ---------------------------------------------------------------------

    @property
    def width(self) -> int:
        """Frame width in pixels."""
        return int(self._core.width)

    @property
    def height(self) -> int:
        """Frame height in pixels."""
        return int(self._core.height)

    @property
    def fps(self) -> float:
        """Frames per second."""
        return float(self._core.fps)

    @property
    def duration(self) -> float:
        """Length in seconds (the file's, or up to and including the last key)."""
        return float(self._core.duration)

    @property
    def frame_count(self) -> int:
        """Number of frames, ``ceil(duration * fps)`` (at least 1)."""
        return int(self._core.frame_count)

    @property
    def render_bytes(self) -> int:
        """The rough peak memory of rendering the scene in one process, in bytes: about 80
        per pixel of the frame, and per layer 12 per pixel and 148 per node of its solver
        grid (every ``grid_step``-th pixel), 1,300 per thin node of that grid (strands,
        teeth, outlines: factored exactly); and once, 160 per node of the largest torn grid
        (the slow modes a long solve deflates, at most 256 MiB). Loading refuses a scene whose estimate does not fit in the memory
        free now; a Ray render gives each worker this much."""
        return int(self._core.render_bytes)

    @property
    def times(self) -> np.ndarray:
        """The time of every frame in seconds, float64 ``(frame_count,)``."""
        return np.arange(self.frame_count, dtype=np.float64) / self.fps

    @property
    def layers(self) -> list[str]:
        """Layer names, back to front."""
        return list(self._core.layer_names)

    @property
    def features(self) -> list[str]:
        """Feature ids, in file order."""
        return list(self._core.feature_ids)

    def __repr__(self) -> str:
        source = f" from {self.file!r}" if self.file else ""
        return (
            f"<inkwarp.Scene{source}: {self.width}x{self.height}, {self.frame_count} frames at "
            f"{self.fps:g} fps, layers {self.layers}>"
        )

    # ---- rendering ----------------------------------------------------------------------

    def _time(self, time: float | None, frame: int | None, frame_too: bool = True) -> float:
        """``time`` or ``frame``'s time, checked (a time past the end warned of; ``frame_too``:
        the caller takes ``frame=`` too, which the warning then offers)."""
        if time is not None and frame is not None:
            raise InputError("give either time= or frame=, not both")
        if frame is not None:
            index = _integer_argument(frame, "frame")
            if not 0 <= index < self.frame_count:
                raise InputError(f"frame {index} is out of range; the scene has frames 0 to {self.frame_count - 1}")
            return float(self._core.frame_time(index))
        if time is None:
            return 0.0
        seconds = _number_argument(time, "time (seconds)")
        if abs(seconds) > _inkwarp.MAX_TIME_S:
            raise InputError(f"time {seconds:g} s is past the times a scene holds (±{_inkwarp.MAX_TIME_S:g} s, "
                             "about 27 hours); give a time within its keys, or frame=")
        if seconds > self.duration:
            from inkwarp.errors import PastEndWarning, caller_outside

            warnings.warn(f"time {seconds:g} s is past the scene's end ({self.duration:g} s): it shows the poses "
                          "held after the last keys; give a time up to the end (seconds, not frames: frame "
                          f"N is at N / fps{', or give frame=N' if frame_too else ''})", PastEndWarning, stacklevel=caller_outside())
        elif self._before_every_key(seconds):
            from inkwarp.errors import PastEndWarning, caller_outside

            warnings.warn(f"time {seconds:g} s is before the scene's start (0 s): it shows the poses held "
                          "before the first keys; give a time from 0 to the end", PastEndWarning,
                          stacklevel=caller_outside())
        return seconds

    def _before_every_key(self, seconds: float) -> bool:
        """Whether ``seconds`` is before 0 and before every key (so it shows the first keys'
        poses held; keys may lie before 0 on purpose, and between them a time there moves)."""
        if seconds >= 0:
            return False
        times = [key["t"] for feature in self.to_dict().get("features", []) for key in feature.get("keys", [])]
        return seconds < min(times, default=0.0)

    def _layer_index(self, layer: str | int | None) -> int:
        names = self.layers
        if layer is None:
            if len(names) == 1:
                return 0
            raise InputError(f"the scene has {len(names)} layers ({', '.join(names)}); choose one with layer=NAME")
        if isinstance(layer, (int, np.integer)) and not isinstance(layer, bool):
            if not 0 <= int(layer) < len(names):
                raise InputError(f"layer index {layer} is out of range; the scene has {len(names)} "
                                 f"layer{'s' if len(names) != 1 else ''}")
            return int(layer)
        if layer in names:
            return names.index(layer)
        where = f"{self.file}: " if self.file else ""
        raise InputError(f"{where}no layer is called {layer!r}; the layers are {', '.join(names)}")

    def render(self, time: float | None = None, frame: int | None = None, *, method: str | None = None) -> np.ndarray:
        """The frame at ``time`` seconds (or frame number ``frame``; default: time 0).

        Every layer is solved from scratch (no warm start); :meth:`frames` is faster for
        consecutive frames. A sequence's frames are warm-started, so frame ``N`` here can
        differ from the sequence's frame ``N`` by a level or so where the solve's tolerance
        allows; ``next(iter(scene.frames(N, N + 1)))`` is the sequence's frame pixel for
        pixel (as ``inkwarp render --frame N`` is), at the cost of its warm-start chain.

        Parameters
        ----------
        time, frame : optional
            When (default: time 0). Give one of them. ``time`` is in seconds, within ±10⁵ s
            (``ValueError`` past that); a time before 0 is the drawing before the first
            frame (keys may lie there), and a time past the scene's end (:attr:`duration`)
            gives the poses held after the last keys with a :class:`~inkwarp.PastEndWarning`.
            ``frame`` is one of the scene's frames, 0 to ``frame_count - 1``.
        method : str, optional
            ``"tps"``, ``"tps-exact"``, ``"triangulation"`` or ``"beier-neely"`` for every
            layer instead of the scene's ``solver.method``.

        Returns
        -------
        ndarray
            RGBA uint8 ``(height, width, 4)``, straight alpha.
        """
        return self._core.render(self._time(time, frame), _method_argument(method))

    def field(
        self,
        time: float | None = None,
        frame: int | None = None,
        layer: str | int | None = None,
        *,
        method: str | None = None,
    ) -> np.ndarray:
        """The displacement field of one layer at ``time`` seconds (or frame ``frame``).

        Parameters
        ----------
        time, frame : optional
            When (default: time 0). Give one of them, as for :meth:`render` (a time past
            the scene's end warns).
        layer : str or int, optional
            Layer name or index; may be left out when the scene has one layer.
        method : str, optional
            The interpolant instead of the layer's ``solver.method`` (see :meth:`render`).

        Returns
        -------
        ndarray
            float32 ``(height, width, 2)``: pixel ``(x, y)`` of the layer's rest image moves
            to ``(x + f[y, x, 0], y + f[y, x, 1])``.
        """
        index = self._layer_index(layer)
        at = self._time(time, frame)
        field = self._core.field(index, at, _method_argument(method))
        _check_finite_field(field, f"layer {self.layers[index]!r} at t = {at:g} s")
        return field

    def frames(
        self, start: int = 0, stop: int | None = None, *, threads: int | None = None, method: str | None = None
    ) -> Frames:
        """Frames ``start`` to ``stop - 1``, each warm-started from the one before.

        Frames are solved in chains of 16 (frame numbers that are multiples of 16 start a
        chain cold); chains render in parallel on ``threads`` threads. A range that starts
        inside a chain first solves that chain's earlier frames (a pre-roll of at most 15
        frames, solved and dropped; none where no layer warm-starts, see
        :func:`inkwarp.rendering.warm_starts`), so every frame is the one a sequential
        render gives, pixel for pixel, as with ``inkwarp render --frames``. The solver and the
        renderer already use every core inside a frame, so the default is one thread per
        four cores, and no more than the free memory holds renders of the scene
        (:attr:`render_bytes` each: every thread keeps its own solvers). The pixels do not
        depend on the number of threads.

        Parameters
        ----------
        start, stop : int
            Frame range, like ``range(start, stop)``; ``stop`` defaults to the end, and one
            past the end is cut to it, as a slice is.
        threads : int, optional
            Worker threads; 1 renders on the calling thread only.
        method : str, optional
            The interpolant instead of each layer's ``solver.method`` (see :meth:`render`).

        Returns
        -------
        Frames
            An iterator of RGBA uint8 ``(height, width, 4)`` arrays with ``len()``.
        """
        given = self.frame_count if stop is None else _integer_argument(stop, "stop")
        start, stop = _integer_argument(start, "start"), min(given, self.frame_count)
        if start < 0 or stop < start:
            raise InputError(f"frames({start}, {given}) is not a range of this scene's frames 0 to "
                             f"{self.frame_count - 1}: give 0 <= start <= stop (a stop past the end "
                             "is cut to it)")
        if threads is not None and not 1 <= _integer_argument(threads, "threads") <= 4096:
            raise InputError(f"threads must be from 1 to 4096, got {threads}")
        method = _method_argument(method)
        first = preroll_start(start) if start < stop and self._core.warm_starts(method) else start
        core = self._core.frames(first, stop, 0 if threads is None else int(threads), method)
        return Frames(core, start, start - first)

    # ---- the document -------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The scene as a dict in the scene format, defaults filled in; ``width`` and
        ``height`` only where the scene gives them (otherwise they are its images' size,
        ``Scene.width`` and ``Scene.height``), so the dict stays sized by its images."""
        return json.loads(self._core.doc_json())

    def save(self, path: str | os.PathLike[str]) -> None:
        """Writes the scene as JSON; relative image paths are rewritten for the new folder.

        The file name must end in ``.json`` (``ValueError`` otherwise): a slip such as
        ``save("cat.png")`` would replace the scene's own picture with text.
        """
        target = Path(_path_argument(path, "Scene.save's path"))
        if target.suffix.lower() != ".json":
            raise InputError(f"{target}: a scene is saved as JSON; name the file .json, such as "
                             f"{target.with_suffix('.json').name}")
        data = self.to_dict()
        if self.base_dir is not None:
            for layer in data.get("layers", []):
                for key in ("image", "alpha", "continuity"):
                    reference = layer.get(key)
                    if reference and not reference.lower().startswith("data:") and not os.path.isabs(reference):
                        absolute = Path(self.base_dir) / reference
                        layer[key] = Path(os.path.relpath(absolute, target.resolve().parent)).as_posix()
        from inkwarp._atomic import write_text

        write_text(target, json.dumps(data, indent=2) + "\n", suffix=".json")

    def notes(self) -> list[Problem]:
        """What in this scene is allowed but probably a mistake, as ``(JSON path, message)``:
        a feature drawn wholly off the picture (it moves and tears nothing), one drawn wholly
        on holes of the layers it drives (transparent pixels, by default: the solver drops
        its samples, so it pins nothing; judged on the visible layers it drives, at
        ``grid_step`` 1 only), a key after the scene's end (no frame shows it) or one before
        its start that frame 0 is part way from, or one whose points lie further off the picture
        than its longer side, a feature that
        drives no layer, a line, curve or region whose points are all at one place, a region
        with no area, a layer picture with a colour profile other than sRGB's (not applied:
        it renders duller than a viewer shows it), a layer whose matte falls into more pieces
        on the coarse grid of its ``grid_step`` than at full resolution (hair and thin
        strands come apart there), a shown layer with no opaque pixel, every layer hidden.
        ``inkwarp validate``
        prints them as notes after its "ok"; a scene with notes renders as any other (a
        feature off the picture may be there on purpose, as a correspondence point for
        :func:`inkwarp.transfer`).
        """
        doc = self.to_dict()
        width, height, duration = self.width, self.height, self.duration
        layers = doc.get("layers", [])
        notes: list[Problem] = []
        # Per layer, the features whose every sample the solver drops (None at grid_step > 1).
        checks = self._core.layer_checks()
        dropped = [None if wholly is None else set(wholly) for wholly, *_ in checks]

        def shown(drives: list[int]) -> list[int]:  # the visible ones, or all where none is
            return [j for j in drives if layers[j].get("visible", True)] or drives

        for i, feature in enumerate(doc.get("features", [])):
            name, rest = feature["id"], np.asarray(feature["rest"], dtype=np.float64).reshape(-1, 2)
            drives = [j for j, layer in enumerate(layers) if layer.get("features") is None or name in layer["features"]]
            low, high = rest.min(axis=0), rest.max(axis=0)
            # A node takes the samples within half a pixel of its centre; a spline may swing a
            # little past its control points, so its box is widened by a quarter of its size
            # (straight segments stay within their vertices' box).
            curved = feature["kind"] == "spline" or feature.get("curve") == "spline"
            margin = 0.5 + (0.25 * (high - low) if curved else np.zeros(2))

            def outside(at: Sequence[float]) -> bool:  # off the picture placed at `at`
                return bool((high + margin < at).any() or (low - margin > np.add(at, [width - 1, height - 1])).any())

            # Off the frame and off every layer it drives, as placed by its offset (a layer
            # moved past the frame's edge can be pulled into view).
            if outside([0, 0]) and all(outside(layers[j].get("offset", [0, 0])) for j in drives):
                does = "tears" if feature["kind"] == "cut" else "moves"
                notes.append((f"features[{i}]", f"{name!r} lies wholly off the picture, so it {does} nothing: its rest "
                              f"points span x {low[0]:g} to {high[0]:g}, y {low[1]:g} to {high[1]:g}, the picture's pixel "
                              f"centres x 0 to {width - 1}, y 0 to {height - 1}"))
            # Judged on the layers it drives that are drawn: a hidden layer's field moves nothing seen.
            elif feature["kind"] != "cut" and shown(drives) and all(dropped[j] is not None and i in dropped[j] for j in shown(drives)):
                where = " and ".join(f"the holes of the continuity matte of layer {layers[j]['name']!r}" if layers[j].get("continuity")
                                     else f"the transparent pixels of layer {layers[j]['name']!r}" for j in shown(drives))
                if (low < -0.5).any() or (high > [width - 0.5, height - 0.5]).any():
                    where += " and off the picture"
                notes.append((f"features[{i}]", f"{name!r} lies wholly on {where}, so it pins and moves nothing; "
                              "trace it on the picture itself"))
            if not drives:
                notes.append((f"features[{i}]", f"{name!r} drives no layer: every layer lists its features "
                              "and none lists it; add it to a layer's features"))
            if feature["kind"] in ("polyline", "spline", "region") and (rest == rest[0]).all():
                notes.append((f"features[{i}].rest", f"{name!r}, a {feature['kind']}, has all its points at one "
                              f"place ({rest[0][0]:g}, {rest[0][1]:g}): it holds that one pixel, as a point does; "
                              "spread its points along what it traces"))
            elif feature["kind"] == "region" and np.linalg.svd(rest - rest.mean(axis=0), compute_uv=False)[-1] < 1e-9:
                notes.append((f"features[{i}].rest", f"{name!r}, a region, has no area (its points lie on one line): "
                              "it holds nothing inside, only its outline, as a polyline does; trace around what "
                              "it should hold"))
            notes += self._outside_keys_of(i, feature)
        # At a grid_step above 1: a matte that falls apart on the coarse grid (hair, strands).
        features = doc.get("features", [])
        for j, (_, pieces, blank, still) in enumerate(checks):
            if blank and layers[j].get("visible", True):
                notes.append((f"layers[{j}]", f"layer {layers[j]['name']!r} has no opaque pixel (its picture is wholly "
                              "transparent): it shows nothing; give it a picture with opaque pixels, or remove it"))
            elif still and layers[j].get("continuity"):
                notes.append((f"layers[{j}]", f"layer {layers[j]['name']!r}'s continuity matte has no nonzero pixel: "
                              "its picture shows, but nothing moves it; give the matte nonzero pixels where the "
                              "picture should move, or drop \"continuity\""))
            if pieces is None:
                continue
            step, fine, coarse, clashes = pieces
            if coarse > fine:
                notes.append((f"layers[{j}]", f"at grid_step {step} the matte of layer {layers[j]['name']!r} falls "
                              f"into {coarse} pieces on the coarse grid it is solved on, against {fine} at full "
                              "resolution: parts thinner than the step (hair, strands, thin necks) come apart there, "
                              "and their pixels move with a neighbouring part, unbent; use grid_step 1 for this layer"))
            # Features closer than the step that move apart (lids that close, lips): the coarse
            # grid holds one of them where they meet, and the picture tears between them.
            if clashes:
                named = [f"{features[a]['id']!r} and {features[b]['id']!r}" if a != b else
                         f"two parts of {features[a]['id']!r}" for a, b in clashes[:3]]
                more = f" (and {len(clashes) - 3} more pairs)" if len(clashes) > 3 else ""
                notes.append((f"layers[{j}]", f"at grid_step {step}, on layer {layers[j]['name']!r}, {'; '.join(named)}{more} "
                              f"lie within {step} px of each other and move apart: the coarse grid holds only one of "
                              "each pair where they meet, and the picture tears between them; use a smaller "
                              "grid_step (1 solves every pixel)"))
        if layers and not any(layer.get("visible", True) for layer in layers):
            notes.append(("layers", "every layer is hidden (\"visible\": false), so every frame shows the background "
                          "alone; set \"visible\": true on the layers to draw"))
        return notes + self._profile_notes(layers)

    def _profile_notes(self, layers: list[dict[str, Any]]) -> list[Problem]:
        """Notes on layer pictures (files, not ``data:`` URIs) in a colour space other than
        sRGB, whose profile the engine does not apply."""
        from PIL import Image

        from inkwarp.importing import _foreign_profile

        notes: list[Problem] = []
        for j, layer in enumerate(layers):
            reference = layer.get("image")
            if not isinstance(reference, str) or reference[:5].lower() == "data:":
                continue
            try:
                with Image.open(Path(self.base_dir or ".") / reference) as image:
                    profile = _foreign_profile(image)
            except (OSError, ValueError, SyntaxError):
                continue
            if profile is not None:
                notes.append((f"layers[{j}].image", f"layer {layer.get('name')!r}'s picture carries a colour profile "
                              f"({profile[1] or 'unreadable'}) that inkwarp does not apply: its numbers render "
                              "as sRGB, duller than a viewer shows them; convert the picture to sRGB (inkwarp new "
                              "does so)"))
        return notes

    def _outside_keys(self, still: bool = False) -> list[Problem]:
        """The notes on keys after the scene's end or before its start, or far off the picture
        (:meth:`notes`); ``inkwarp render`` gives them too, since they cut the animation short
        at either end or smear it. ``still``: only those a single frame shows (far off)."""
        return [note for i, feature in enumerate(self.to_dict().get("features", [])) for note in self._outside_keys_of(i, feature, still)]

    def _outside_keys_of(self, i: int, feature: dict[str, Any], still: bool = False) -> list[Problem]:
        """The notes on the keys of ``feature`` (``features[i]``) whose points lie further off
        the picture than its longer side (pasted from a larger tracing, or in other units), and
        unless ``still``, on those after the scene's end or before its start (0 s)."""
        duration, keys, notes = self.duration, feature.get("keys", []), []
        (w, h), points = (self.width, self.height), [np.asarray(key.get("points") or [], np.float64).reshape(-1, 2) for key in keys]
        # (A feature at rest off the picture pulls nothing: its samples are dropped.)
        pulls = feature["kind"] != "cut" and not off_picture(np.asarray(feature["rest"], np.float64).reshape(-1, 2), w, h, 0.5).all()
        far = [k for k, p in enumerate(points) if pulls and off_picture(p, w, h, max(w, h)).any()]
        if far:
            (x0, y0), (x1, y1) = points[far[0]].min(axis=0), points[far[0]].max(axis=0)
            more = f" (and {len(far) - 1} more of its keys)" if len(far) > 1 else ""
            notes.append((f"features[{i}].keys[{far[0]}].points",
                          f"{feature['id']!r} has a key at {keys[far[0]]['t']:g} s{more} whose points reach x {x0:g} to "
                          f"{x1:g}, y {y0:g} to {y1:g}, further off the picture ({w} x {h}) than its "
                          "longer side: the surface is pulled that far, and the picture smears; were the points "
                          "traced on a larger picture? scale them to this one"))
        for k, key in enumerate(keys if not still else []):
            if key["t"] > duration + 1e-9:
                notes.append((f"features[{i}].keys[{k}].t",
                              f"{feature['id']!r} has a key at {key['t']:g} s, after the scene's end ({duration:g} s): "
                              f"no frame shows it, the frames before it show the move toward it; a duration of "
                              f"{key['t'] + 1 / self.fps:g} s ends on it, or move the key"))
            # The last key before 0 s with one after 0 s: frame 0 is part way between them
            # (unless the key holds its pose until the next).
            elif key["t"] < -1e-9 and k + 1 < len(keys) and keys[k + 1]["t"] > 1e-9 and key.get("interpolation") != "hold":
                notes.append((f"features[{i}].keys[{k}].t",
                              f"{feature['id']!r} has a key at {key['t']:g} s, before the scene's start (0 s): no "
                              f"frame shows it, and frame 0 is already part way to the key at {keys[k + 1]['t']:g} s; "
                              "unless that is meant, move the key to 0 s"))
        return notes

    def validate(self) -> list[Problem]:
        """Every problem of this scene's document now (images are read again).

        A scene that loaded has none, unless its image files changed since.
        """
        return _inkwarp.scene_problems(self._core.doc_json(), self.base_dir)
