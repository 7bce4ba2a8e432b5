"""Writers for rendered frames: one PNG, a PNG sequence, an animated GIF, an H.264 MP4
(:func:`open_writer` hands the formats with alpha, WebM, MOV and APNG, to
:mod:`inkwarp.outputs`).

Every writer works under a temporary name in the target's own directory and renames it to
the target only when the last frame is in, so a render that fails or is interrupted leaves
nothing behind (and an existing file of the same name stays as it was until then).

Frames are RGBA ``uint8`` arrays of shape ``(H, W, 4)`` with straight alpha, as
:meth:`inkwarp.Scene.render` returns them. A GIF's alpha is 1-bit (pixels with alpha < 128
are transparent); an MP4 has none, so its frames are flattened over white first. Give the
scene an opaque ``background`` to choose the colour yourself.

Examples
--------
>>> import numpy as np, tempfile, os
>>> from inkwarp.video import open_writer
>>> frame = np.zeros((32, 48, 4), np.uint8); frame[..., 3] = 255
>>> out = os.path.join(tempfile.mkdtemp(), "clip.gif")
>>> with open_writer(out, fps=12) as writer:
...     for shade in range(0, 250, 50):
...         frame[..., 0] = shade
...         writer.write(frame)
>>> [os.path.basename(p) for p in writer.paths]
['clip.gif']
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import warnings
from pathlib import Path
from types import TracebackType
from typing import Any, Literal

import numpy as np

from inkwarp._atomic import clean_stale, temp_path
from inkwarp.errors import InputError

OutputKind = Literal["png", "dir", "gif", "mp4", "webm", "mov", "apng"]

#: Output suffixes that name a file; anything else names a directory of PNG frames.
FILE_SUFFIXES = {".png": "png", ".gif": "gif", ".mp4": "mp4",
                 # with alpha, written by inkwarp.outputs
                 ".webm": "webm", ".mov": "mov", ".apng": "apng"}

#: The names of the frames in a PNG sequence: ``frame_0000.png``, ``frame_0001.png``, ...
FRAME_PATTERN = "frame_{:04d}.png"


def output_kind(path: str | os.PathLike[str]) -> OutputKind:
    """Which writer a path asks for, from its suffix.

    ``.png`` is one frame, ``.gif`` an animated GIF, ``.mp4`` an H.264 video, ``.webm``,
    ``.mov`` and ``.apng`` videos with alpha (VP9, ProRes 4444, animated PNG); an existing
    directory, a path ending in a separator, or a path without a suffix is a directory of
    PNG frames. Any other suffix is a ``ValueError``.

    Examples
    --------
    >>> output_kind("a.gif"), output_kind("frames/"), output_kind("shot.MP4")
    ('gif', 'dir', 'mp4')
    """
    text = os.fspath(path)
    p = Path(text)
    if text.endswith(("/", os.sep)) or p.is_dir():
        return "dir"
    suffix = p.suffix.lower()
    if suffix in FILE_SUFFIXES:
        return FILE_SUFFIXES[suffix]  # type: ignore[return-value]
    if suffix == "":
        return "dir"
    if suffix == ".json":
        # A scene's own name given as the output, most likely: no folder hint.
        raise InputError(f"{text}: a .json name is a scene, not an output; name the output .png (one "
                         f"frame), .gif, .mp4, .webm, .mov, .apng, or a folder of PNG frames (end it with /); "
                         f"such as {p.with_suffix('.gif').name}")
    raise InputError(
        f"{text}: cannot write '{suffix}' files; name the output .png (one frame), "
        ".gif, .mp4, .webm, .mov, .apng, or a directory (a PNG sequence: end the name with "
        f"/, as in {text}{os.sep}, for a folder whose name has a dot)"
    )


def check_target(path: str | os.PathLike[str], kind: OutputKind | None = None) -> Path:
    """Check up front that ``path`` can be written, before any rendering starts.

    ``kind`` is the output's kind if known (default: :func:`output_kind` of ``path`` as
    given: the returned ``Path`` has lost a trailing separator, which is what makes
    ``shot_v1.2/`` a directory). Raises ``ValueError`` with the fix when the parent
    directory is missing or is not a directory, when a file output names an existing
    directory, or when a directory output names an existing file.
    """
    kind = kind or output_kind(path)
    target = Path(os.fspath(path))
    if kind != "dir":
        return check_file(target)
    check_not_a_stream(path)
    parent = _check_parent(target)
    if target.exists() and not target.is_dir():
        raise InputError(f"{target}: is a file, not a directory for PNG frames; name a new folder "
                         f"(end it with /) or the file to write, such as {target.name}.mp4")
    # An existing folder takes the frames itself (its parent may be read-only, as a
    # writable frames folder in a locked shot folder is); a new one is made in the parent.
    if target.is_dir():
        check_writable(target, target, "the directory")
    else:
        check_writable(target, parent)
    return target


def check_file(path: str | os.PathLike[str], suffix: str = "") -> Path:
    """Check up front that a file can be written at ``path`` (any command's output): its
    folder exists, is a folder and is writable, and ``path`` is not a folder. Raises
    ``ValueError`` naming ``path`` and the fix (a file name with ``suffix`` where the path
    has none)."""
    text = os.fspath(path)
    target = Path(text)
    check_not_a_stream(text, suffix)
    if text.endswith(("/", os.sep)):
        raise InputError(f"{text}: names a directory (it ends in {text[-1]}); name a file, such as "
                         f"{target / 'out'}{suffix}")
    parent = _check_parent(target)
    try:
        folder = target.is_dir()
    except OSError as err:  # a name too long for the file system, ...
        raise InputError(f"{target}: {err.strerror or err}; name the output otherwise") from None
    if folder:
        raise InputError(f"{target}: is a directory; name a file, such as {target / 'out'}{target.suffix or suffix}")
    check_writable(target, parent)
    return target


#: Names of the standard streams, which an output cannot be: every output is written under
#: a temporary name and renamed into place.
_STREAMS = {"-": "standard output", "/dev/stdout": "standard output", "/dev/fd/1": "standard output",
            "/proc/self/fd/1": "standard output", "/dev/stderr": "standard error",
            "/dev/fd/2": "standard error", "/proc/self/fd/2": "standard error",
            "/dev/stdin": "standard input", "/dev/fd/0": "standard input", "/proc/self/fd/0": "standard input"}


def check_not_a_stream(path: str | os.PathLike[str], suffix: str = "") -> None:
    """Refuse an output that is not a file inkwarp can write: standard output (``-``,
    ``/dev/stdout``) or another stream, a device or a pipe. Outputs are written under a
    temporary name beside the target and renamed into place, so they go to files only; the
    ``ValueError`` says so and names a file to give instead (with ``suffix`` where the path
    has none).

    Examples
    --------
    >>> check_not_a_stream("/dev/stdout")
    Traceback (most recent call last):
    ...
    ValueError: /dev/stdout: is standard output, not a file; inkwarp writes every output to a file (under a temporary name, renamed when complete), so it cannot write to a stream. Name a file, such as out.gif, or a folder for PNG frames, such as frames/
    """
    import stat

    text = os.fspath(path)
    what = _STREAMS.get(text.rstrip("/") or text)
    if what is None and re.fullmatch(r"/dev/fd/\d+|/proc/(self|\d+)/fd/\d+", text):
        what = "a stream of a process"
    if what is None:
        try:
            mode = os.stat(text).st_mode
        except (OSError, ValueError):
            return
        if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
            return
        what = "a pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device"
    given = Path(text).suffix if text not in _STREAMS else ""
    example = f"out{given or suffix}" if given or suffix else "out.gif, or a folder for PNG frames, such as frames/"
    raise InputError(f"{text}: is {what}, not a file; inkwarp writes every output to a file (under a temporary "
                     f"name, renamed when complete), so it cannot write to a stream. Name a file, such as {example}")


def check_writable(target: Path, folder: Path, named: str | None = None) -> None:
    """A ``ValueError`` naming ``target`` and the fix unless ``folder`` (said as ``named``,
    by default "the directory FOLDER") may be written in."""
    if not os.access(folder, os.W_OK):
        raise InputError(f"{target}: {named or f'the directory {folder}'} is not writable; choose a writable "
                         "folder or change its permissions")


def _check_parent(target: Path) -> Path:
    parent = target.absolute().parent
    if not parent.exists():
        raise InputError(f"{target}: the directory {parent} does not exist; create it first")
    if not parent.is_dir():
        raise InputError(f"{target}: {parent} is not a directory")
    return parent


def flatten(rgba: np.ndarray, background: tuple[int, int, int] = (255, 255, 255)) -> np.ndarray:
    """RGB ``uint8`` of a straight-alpha RGBA frame composited over an opaque colour.

    Examples
    --------
    >>> px = np.array([[[200, 0, 0, 128]]], np.uint8)
    >>> flatten(px).tolist()
    [[[227, 127, 127]]]
    """
    frame = _as_frame(rgba)
    if frame.shape[2] == 3:
        return frame
    alpha = frame[..., 3:4].astype(np.uint32)
    if alpha.min() == 255:
        return np.ascontiguousarray(frame[..., :3])
    rgb = frame[..., :3].astype(np.uint32)
    bg = np.asarray(background, np.uint32)
    return ((rgb * alpha + bg * (255 - alpha) + 127) // 255).astype(np.uint8)


def _as_frame(frame: np.ndarray) -> np.ndarray:
    arr = np.asarray(frame)
    if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] not in (3, 4):
        raise InputError(
            f"a frame must be a uint8 array of shape (H, W, 4) or (H, W, 3); got {arr.dtype} "
            f"{arr.shape}"
        )
    return arr


#: An MP4's frames are flattened over white; the warning names frames with a pixel whose
#: alpha is under this. An opaque picture's outer pixels can come out at 252-254 where
#: the field squeezes the surface at the picture's edge (a held border beside a large
#: move): over white they change by at most 3 levels, under the encoder's own error.
SEE_THROUGH_ALPHA = 250

#: What to do when a write fails for each of the reasons a disk gives.
_WRITE_FIXES = {
    errno.ENOSPC: "free space on that disk or write the output to another one",
    errno.EDQUOT: "free space within your quota or write the output to another disk",
    errno.EFBIG: "the file system's or the process's file-size limit (ulimit -f) allows no "
                 "more; raise the limit or write the output to another disk",
    errno.EIO: "check the disk, or write the output to another one",
}
#: The reasons that mean the disk took no more (not a failing device, EIO).
DISK_FULL = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})

#: How ffmpeg reports those reasons in its messages.
_FFMPEG_REASONS = {"No space left on device": errno.ENOSPC, "Disk quota exceeded": errno.EDQUOT,
                   "File too large": errno.EFBIG, "Input/output error": errno.EIO}


def write_failure(target: Path, err: OSError) -> OSError:
    """The error for an output that could not be written because of ``err``: where that is
    a disk's reason (full, quota, file-size limit, I/O), one
    :class:`~inkwarp.errors.OutputWriteError` naming the output, the reason and the fix;
    any other error as it is."""
    from inkwarp.errors import OutputWriteError

    if isinstance(err, OutputWriteError) or err.errno not in _WRITE_FIXES:
        return err
    return disk_failure(f"{target}: {'the frames' if target.is_dir() or not target.suffix else 'the file'}", err)


def disk_failure(subject: str, err: OSError) -> OSError:
    """The :class:`~inkwarp.errors.OutputWriteError` saying that ``subject`` could not be
    written for ``err``'s reason, one of :data:`_WRITE_FIXES`, and what to do."""
    from inkwarp.errors import OutputWriteError

    failure = OutputWriteError(f"{subject} could not be written ({os.strerror(err.errno)}); {_WRITE_FIXES[err.errno]}")
    failure.errno = err.errno
    return failure


def ffmpeg_failure(target: Path, code: int, said: str) -> OSError:
    """The error for ffmpeg exiting with ``code`` (negative: killed by that signal) having
    said ``said``: :func:`write_failure` where it could not write (a full disk; SIGXFSZ is
    a file-size limit), otherwise ffmpeg's own words."""
    import signal

    reason = next((number for text, number in _FFMPEG_REASONS.items() if text in said), None)
    if code == -getattr(signal, "SIGXFSZ", 0):
        reason = errno.EFBIG
    if reason is not None:
        return write_failure(target, OSError(reason, os.strerror(reason)))
    if code < 0:
        how = f"killed by {signal.Signals(-code).name} ({signal.strsignal(-code)})"
    else:
        how = f"exit status {code}"
    words = " ".join(said.split())[-400:]
    return OSError(f"{target}: ffmpeg failed ({how})" + (f": {words}" if words else
                                                         ": it gave no reason"))


def check_fps(fps: float, name: str = "fps") -> float:
    """``fps`` as a float when it is a rate a scene may have (from ``MIN_FPS``, 0.001: a
    frame every 1000 s, to ``MAX_FPS``, 1000; see docs/reference/limits.md), else a
    ``ValueError`` naming ``name``.

    Examples
    --------
    >>> check_fps(24)
    24.0
    >>> check_fps(1e-9)
    Traceback (most recent call last):
    ...
    ValueError: fps must be a number of frames per second from 0.001 (one frame every 1000 s) to 1000; got 1e-09
    """
    from inkwarp._inkwarp import MAX_FPS, MIN_FPS

    try:
        rate = float(fps)
    except (TypeError, ValueError):
        rate = float("nan")
    if not MIN_FPS <= rate <= MAX_FPS:  # NaN too
        raise InputError(f"{name} must be a number of frames per second from {MIN_FPS:g} (one frame every "
                         f"{1 / MIN_FPS:g} s) to {MAX_FPS:g}; got {fps!r}")
    return rate


def ffmpeg_rate(fps: float) -> str:
    """``fps`` as the fraction ffmpeg takes for a frame rate, ``NUM/DEN``: the nearest one
    whose terms stay within what ffmpeg reads exactly (about 10**6), so 0.001 is 1/1000 and
    NTSC's 30000/1001 stays itself (fractions of terms up to 1001 made 0/1 of a rate under
    1/2002 fps, which ffmpeg refused, and rounded slow ones: 0.0015 fps as 1/667).

    Examples
    --------
    >>> ffmpeg_rate(24), ffmpeg_rate(30000 / 1001), ffmpeg_rate(0.001), ffmpeg_rate(0.0015)
    ('24/1', '30000/1001', '1/1000', '3/2000')
    """
    import math
    from fractions import Fraction

    fraction = Fraction(fps).limit_denominator(1_001_000 // max(1, math.ceil(fps)))
    return f"{fraction.numerator}/{fraction.denominator}"


#: ffmpeg's arguments that convert RGB frames to Y'CbCr by the BT.709 matrix (limited range)
#: and tag the video as BT.709 (primaries, transfer and matrix): untagged, ffmpeg used the
#: BT.601 matrix, which players and editors assume only for standard definition, so HD
#: colours came back shifted (200, 50, 50 as 212, 62, 47).
BT709 = ["-vf", "setparams=color_primaries=bt709:color_trc=bt709:colorspace=bt709:range=tv,"
         "scale=out_color_matrix=bt709:out_range=tv"]


def _temp_name(target: Path, suffix: str) -> Path:
    """A new empty file beside ``target``, created with the permissions of any new file
    (0o666 less the umask: mkstemp's 0o600 would survive the rename); its name carries
    the process id so that a later run can remove it if this one is killed."""
    return temp_path(target, suffix)


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically: under a temporary name beside it, renamed at
    the end, so ``path`` is either complete or as it was.

    Examples
    --------
    >>> import os, tempfile
    >>> target = os.path.join(tempfile.mkdtemp(), "notes.txt")
    >>> write_bytes(target, b"hello").read_bytes()
    b'hello'
    """
    target = Path(os.fspath(path))
    temp = _temp_name(target, "")
    try:
        temp.write_bytes(data)
        os.replace(temp, target)
    except BaseException:
        temp.unlink(missing_ok=True)
        raise
    return target


def _temp_dir(target: Path) -> Path:
    """A new empty directory for the frames bound for the folder ``target``: inside it
    when it exists (its parent need not be writable), else beside it (0o777 less the
    umask). Stale ones of killed runs go first, beside it too."""
    if not target.is_dir():
        return temp_path(target, directory=True)
    clean_stale(target)  # (left beside it before the folder existed)
    return temp_path(target / ".frames", directory=True)


class FrameWriter:
    """Writes frames to one target; a context manager that commits or leaves nothing.

    Use :func:`open_writer` to get the right writer for a path. ``write(frame)`` appends a
    frame; leaving the ``with`` block normally calls :meth:`close` (which renames the
    temporary output into place and fills :attr:`paths`); leaving it by an exception calls
    :meth:`abort` (which deletes it).
    """

    def __init__(self, target: Path, fps: float) -> None:
        check_fps(fps)
        self.target = target
        self.fps = float(fps)
        self.frames_written = 0
        self.size: tuple[int, int] | None = None  # (width, height)
        #: The paths written, filled in by :meth:`close`.
        self.paths: list[Path] = []
        self._closed = False

    def write(self, frame: np.ndarray) -> None:
        arr = _as_frame(frame)
        size = (arr.shape[1], arr.shape[0])
        if self.size is None:
            self.size = size
        elif size != self.size:
            raise InputError(f"frame {self.frames_written} is {size[0]}x{size[1]}; the others "
                             f"are {self.size[0]}x{self.size[1]}")
        try:
            self._write(arr)
        except OSError as err:
            raise write_failure(self.target, err) from None
        self.frames_written += 1

    def close(self) -> list[Path]:
        if self._closed:
            return self.paths
        self._closed = True
        if self.frames_written == 0:
            self._discard()
            raise InputError(f"{self.target}: no frames to write")
        try:
            self.paths = self._commit()
        except OSError as err:
            self._discard()
            raise write_failure(self.target, err) from None
        except BaseException:
            self._discard()
            raise
        return self.paths

    def abort(self) -> None:
        if not self._closed:
            self._closed = True
            self._discard()

    def __enter__(self) -> FrameWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # The three steps every writer implements.
    def _write(self, frame: np.ndarray) -> None:
        raise NotImplementedError

    def _commit(self) -> list[Path]:
        raise NotImplementedError

    def _discard(self) -> None:
        raise NotImplementedError


def _save_png(frame: np.ndarray, path: Path | str) -> None:
    from PIL import Image

    from inkwarp.imaging import PNG_COMPRESS_LEVEL

    mode = "RGBA" if frame.shape[2] == 4 else "RGB"
    Image.fromarray(frame, mode).save(path, format="PNG", compress_level=PNG_COMPRESS_LEVEL)


class PngWriter(FrameWriter):
    """Exactly one frame to one PNG file (RGBA, straight alpha), written atomically by
    :func:`inkwarp.imaging.write_png`."""

    def __init__(self, target: Path, fps: float = 24.0) -> None:
        super().__init__(target, fps)
        self._frame: np.ndarray | None = None

    def _write(self, frame: np.ndarray) -> None:
        if self.frames_written:
            raise InputError(f"{self.target}: a .png holds one frame; write a .gif, an .mp4 or "
                             "a directory for more")
        self._frame = frame

    def _commit(self) -> list[Path]:
        from inkwarp.imaging import write_png

        assert self._frame is not None
        write_png(self.target, self._frame)
        self._frame = None
        return [self.target]

    def _discard(self) -> None:
        self._frame = None


class PngSequenceWriter(FrameWriter):
    """Frames as ``frame_0000.png``, ``frame_0001.png``, ... in a directory.

    Files are numbered by frame, from ``first_frame``, so a range of an animation
    (``--frames 24:48``) lands under its own numbers and several ranges can be rendered
    into one directory. The frames go into a fresh temporary directory beside the target
    (inside it, when it exists); at the end that directory becomes the target, or, when the
    target exists, its frames replace the target's files of the same names (other files
    are left as they are).
    """

    def __init__(self, target: Path, fps: float, first_frame: int = 0, frames: int = 1) -> None:
        super().__init__(target, fps)
        self.first_frame = first_frame
        # A folder this run could not fill is refused before any frame is rendered.
        self._check_target(frames)
        self._temp = _temp_dir(target)

    def _check_target(self, count: int) -> None:
        """Refuse an existing target that cannot take ``count`` frames: a folder that cannot
        be written (the error names it), or one where a frame's name is taken by a folder.
        Checked again before the frames move in, so none moves unless all can."""
        if not self.target.is_dir():
            return
        temp_path(self.target / self._name(0)).unlink()
        for i in range(count):
            path = self.target / self._name(i)
            if path.is_dir() and not path.is_symlink():
                raise InputError(f"{path}: a folder stands where frame {self.first_frame + i} goes; "
                                 "move it away or render into another folder")

    def _name(self, i: int) -> str:
        return FRAME_PATTERN.format(self.first_frame + i)

    def _write(self, frame: np.ndarray) -> None:
        name = self._name(self.frames_written)
        try:
            _save_png(frame, self._temp / name)
        except OSError as err:
            raise write_failure(self.target / name, err) from None

    def _commit(self) -> list[Path]:
        names = [self._name(i) for i in range(self.frames_written)]
        if not self.target.exists():
            os.replace(self._temp, self.target)
        else:
            self._check_target(len(names))
            for name in names:
                os.replace(self._temp / name, self.target / name)
            shutil.rmtree(self._temp, ignore_errors=True)
        return [self.target / name for name in names]

    def _discard(self) -> None:
        shutil.rmtree(self._temp, ignore_errors=True)


class GifWriter(FrameWriter):
    """An animated GIF, looping forever, each frame with its own palette, streamed to the
    file frame by frame (memory holds one frame, not the clip).

    GIF's alpha is 1-bit: pixels with alpha < 128 are transparent, the others show their
    own colour; every frame is drawn on a cleared canvas, so moving parts leave no trail.
    Pillow encodes each frame alone (255 colours and the transparent index); its image
    block is copied into the file with the frame's palette as a local colour table. A run
    of identical frames is stored once, with the delays added. GIF stores delays in
    hundredths of a second, so they are spread to keep the clip's total length right
    (24 fps plays as 4, 4, 4, 5, 4, ... hundredths); above 50 fps frames are left out
    (`gif_keeps`). A delay past GIF's 655.35 s is stored as copies of the frame
    (`gif_delay_parts`).
    """

    def __init__(self, target: Path, fps: float) -> None:
        super().__init__(target, fps)
        self._temp: Path | None = None
        self._file: Any = None
        self._kept = 0  # frames kept (see `gif_keeps`), before runs are merged
        # The last frame, written when the next one differs: (its pixels' digest, the
        # encoded image, the delay).
        self._pending: tuple[bytes, bytes, int] | None = None

    def _write(self, frame: np.ndarray) -> None:
        import hashlib
        import io
        import struct

        from PIL import Image

        if not gif_keeps(self.frames_written, self.fps):
            return
        self._kept += 1
        rgba = _as_frame(frame)
        # A frame the same as the last (a held pose) adds its delay to it, unencoded.
        digest = hashlib.blake2b(rgba.tobytes(), digest_size=16).digest()
        delay = gif_delay_cs(self.frames_written, self.fps)
        if self._pending is not None and self._pending[0] == digest:
            self._pending = (digest, self._pending[1], self._pending[2] + delay)
            return
        clear = rgba[..., 3] < 128 if rgba.shape[2] == 4 else np.zeros(rgba.shape[:2], bool)
        colours = np.array(rgba[..., :3])
        colours[clear] = 0  # one colour for the transparent pixels: no palette entries spent on them
        rgb = Image.fromarray(colours, "RGB")
        # The octree keeps saturated colours (eyes, lips) and gives files about half the
        # size of a median cut's, at a mean error of about 3 levels on a photograph.
        quantized = rgb.quantize(colors=255, method=Image.Quantize.FASTOCTREE)
        indexed = np.array(quantized, copy=True)
        indexed[clear] = 255
        image = Image.fromarray(indexed, "P")
        image.putpalette(((quantized.getpalette() or []) + [0] * 768)[:765] + [0, 0, 0])
        one = io.BytesIO()
        image.save(one, format="GIF", optimize=False)
        palette, block = _gif_image_block(one.getvalue())
        if self._file is None:
            self._temp = _temp_name(self.target, ".gif")
            self._file = open(self._temp, "wb")  # noqa: SIM115 - closed by _commit/_discard
            # Header, a screen without a global palette, and the loop-forever extension.
            self._file.write(b"GIF89a" + struct.pack("<HHBBB", rgb.width, rgb.height, 0, 0, 0)
                             + b"\x21\xff\x0bNETSCAPE2.0\x03\x01\x00\x00\x00")
        self._flush_pending()
        self._pending = (digest, block[:9] + bytes([block[9] | 0x80 | _palette_bits(palette)]) + palette + block[10:], delay)

    def _flush_pending(self) -> None:
        import struct

        if self._pending is None:
            return
        _, data, delay = self._pending
        # Graphic control: disposal 2 (the canvas is cleared after the frame, so the next
        # one's transparent pixels show nothing of it), the delay, transparent index 255 (on
        # opaque frames too: decoders then clear to transparent, not to a colour). A delay
        # is 16 bits (655.35 s at most): a longer one (a held pose, a frame at under 0.0015
        # fps) is the same image repeated, the delay shared evenly between the copies.
        for part in gif_delay_parts(delay):
            self._file.write(b"\x21\xf9\x04" + struct.pack("<BHB", 2 << 2 | 1, part, 255) + b"\x00" + data)
        self._file.flush()
        self._pending = None

    def _commit(self) -> list[Path]:
        assert self._file is not None and self._temp is not None
        self._flush_pending()
        self._file.write(b"\x3b")
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()
        self._file = None
        os.replace(self._temp, self.target)
        warn_gif_frames_left_out(self.target, self.frames_written, self._kept, self.fps)
        return [self.target]

    def _discard(self) -> None:
        if self._file is not None:
            try:
                self._file.close()
            except OSError:
                pass  # the buffered rest could not be written either (a full disk): removed below
            self._file = None
        if self._temp is not None:
            self._temp.unlink(missing_ok=True)


#: The most frames a second a GIF plays in browsers: delays are whole hundredths of a
#: second, and a delay of 1 or less plays as 10.
GIF_MAX_FPS = 50


def gif_keeps(i: int, fps: float) -> bool:
    """Whether a GIF at ``fps`` holds frame ``i``: every frame up to :data:`GIF_MAX_FPS`;
    above it, the frame nearest each of its 1/50 s ticks, so the clip keeps its length."""
    if fps <= GIF_MAX_FPS:
        return True
    return round(round(i * GIF_MAX_FPS / fps) * fps / GIF_MAX_FPS) == i


def gif_delay_cs(i: int, fps: float) -> int:
    """Frame ``i``'s delay in hundredths of a second, spread so that the clip keeps its
    length (24 fps plays as 4, 4, 4, 5, 4, ...); 2 above :data:`GIF_MAX_FPS`."""
    if fps > GIF_MAX_FPS:
        return 100 // GIF_MAX_FPS
    return round((i + 1) * 100 / fps) - round(i * 100 / fps)


#: The longest delay one GIF frame holds, in hundredths of a second (16 bits: 655.35 s).
GIF_MAX_DELAY_CS = 0xFFFF


def gif_delay_parts(delay: int) -> list[int]:
    """A delay in hundredths of a second as the delays of the fewest copies of a frame that
    hold it (each at most :data:`GIF_MAX_DELAY_CS`), shared evenly, so that none is so short
    that browsers stretch it (they play a delay of 1 or less as 10).

    Examples
    --------
    >>> gif_delay_parts(4), gif_delay_parts(100_000), gif_delay_parts(0xFFFF + 1)
    ([4], [50000, 50000], [32768, 32768])
    """
    copies = max(1, -(-delay // GIF_MAX_DELAY_CS))
    return [delay * (k + 1) // copies - delay * k // copies for k in range(copies)]


def warn_gif_frames_left_out(target: Path, frames: int, kept: int, fps: float) -> None:
    if kept < frames:
        from inkwarp.errors import InkwarpWarning, caller_outside

        warnings.warn(f"{target.name}: {frames - kept} of its {frames} frames left out, as browsers play "
                      f"a GIF at most {GIF_MAX_FPS} frames a second and the scene has {fps:g}; for every "
                      "frame render a .webm, .mov, .apng or a directory of PNGs", InkwarpWarning, stacklevel=caller_outside())


def _palette_bits(palette: bytes) -> int:
    """The size field of a colour table of ``len(palette) // 3`` entries (2 ** (n + 1))."""
    entries = len(palette) // 3
    return max(0, entries.bit_length() - 2)


def _gif_image_block(data: bytes) -> tuple[bytes, bytes]:
    """``(palette, image block)`` of a one-frame GIF: the palette padded to a power of two,
    and the block from its image descriptor (0x2C) through its data's terminator, with the
    descriptor's colour-table bits cleared."""
    flags = data[10]
    pos = 13
    palette = b""
    if flags & 0x80:
        size = 3 * (2 ** ((flags & 7) + 1))
        palette = data[pos:pos + size]
        pos += size
    while data[pos] == 0x21:  # extensions Pillow may add: skip label and sub-blocks
        pos += 2
        while data[pos]:
            pos += data[pos] + 1
        pos += 1
    if data[pos] != 0x2C:
        raise InputError("Pillow wrote a GIF without an image block")
    descriptor = bytearray(data[pos:pos + 10])
    local = descriptor[9]
    pos += 10
    if local & 0x80:
        size = 3 * (2 ** ((local & 7) + 1))
        palette = data[pos:pos + size]
        pos += size
    descriptor[9] = local & 0x40  # keep the interlace bit only
    start = pos
    pos += 1  # LZW minimum code size
    while data[pos]:
        pos += data[pos] + 1
    pos += 1
    entries = max(2, 1 << max(1, (len(palette) // 3 - 1).bit_length()))
    palette = palette.ljust(3 * entries, b"\0")
    return palette, bytes(descriptor) + data[start:pos]


class Mp4Writer(FrameWriter):
    """An H.264 MP4 (yuv420p, playable everywhere) through the ffmpeg that imageio-ffmpeg
    ships. Frames are streamed to ffmpeg, not kept in memory; ffmpeg's exit status is
    checked, so a full disk or a failed encode is an ``OSError`` with ffmpeg's reason and
    no file under the target's name. H.264 in yuv420p needs even
    sizes, so an odd width or height gets one more column or row, copied from the edge.

    ``quality`` is imageio-ffmpeg's 0-10 scale (10 is best); the default 8 keeps line art
    crisp.
    """

    def __init__(self, target: Path, fps: float, quality: float = 8.0) -> None:
        super().__init__(target, fps)
        self.quality = quality
        self._temp: Path | None = None
        self._pipe: Any = None  # the ffmpeg process, started on the first frame
        self._log: Any = None
        #: Frames that had see-through pixels (alpha under :data:`SEE_THROUGH_ALPHA`,
        #: flattened over white), for the warning when the file is done.
        self.see_through = 0

    def _write(self, frame: np.ndarray) -> None:
        self.see_through += frame.shape[2] == 4 and frame[..., 3].min() < SEE_THROUGH_ALPHA
        rgb = flatten(frame)
        h, w = rgb.shape[:2]
        if h % 2 or w % 2:
            rgb = np.pad(rgb, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        if self._pipe is None:
            self._start(rgb.shape[1], rgb.shape[0])
        assert self._pipe is not None and self._pipe.stdin is not None
        try:
            self._pipe.stdin.write(np.ascontiguousarray(rgb).tobytes())
        except (BrokenPipeError, OSError):
            # ffmpeg stopped reading: its exit status and stderr say why.
            self._finish()
            raise OSError(f"{self.target}: ffmpeg stopped after {self.frames_written} "
                          "frames; it gave no reason") from None

    def _start(self, width: int, height: int) -> None:
        import subprocess
        import tempfile

        import imageio_ffmpeg

        self._temp = _temp_name(self.target, ".mp4")
        # ffmpeg's messages go to a file, not a pipe nobody reads (a full pipe would stall it).
        self._log = tempfile.TemporaryFile()
        crf = int((1 - self.quality / 10.0) * 51)  # imageio-ffmpeg's scale
        command = [
            imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-hide_banner", "-loglevel", "error",
            "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{width}x{height}",
            "-pix_fmt", "rgb24", "-r", ffmpeg_rate(self.fps), "-i", "-", "-an",
            *BT709, "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(crf),
            "-movflags", "+faststart", "-f", "mp4", str(self._temp),
        ]
        self._pipe = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                      stderr=self._log)

    def _finish(self) -> None:
        """Waits for ffmpeg; OSError naming the target and ffmpeg's own words unless it
        exited 0."""
        pipe, self._pipe = self._pipe, None
        if pipe is None:
            return
        try:
            if pipe.stdin is not None:
                pipe.stdin.close()
        except OSError:
            pass
        code = pipe.wait()
        log, self._log = self._log, None
        with log:
            log.seek(0)
            said = log.read().decode("utf-8", "replace").strip().splitlines()
        if code != 0:
            raise ffmpeg_failure(self.target, code, "; ".join(line.strip() for line in said[-3:]))

    def _commit(self) -> list[Path]:
        assert self._temp is not None
        self._finish()  # waits for ffmpeg to finish the file, and checks that it did
        if self._temp.stat().st_size == 0:
            raise OSError(f"{self.target}: ffmpeg wrote an empty file")
        os.replace(self._temp, self.target)
        if self.see_through:
            from inkwarp.errors import InkwarpWarning, caller_outside

            which = f"{self.see_through} of its {self.frames_written} frames"
            warnings.warn(f"{self.target.name}: {which} had transparent pixels, flattened over "
                          "white (an .mp4 has no alpha); for alpha render a .webm, .mov, .apng "
                          "or a directory of PNGs, or give the scene an opaque background",
                          InkwarpWarning, stacklevel=caller_outside())
        return [self.target]

    def _discard(self) -> None:
        if self._pipe is not None:
            try:
                self._pipe.kill()
                if self._pipe.stdin is not None:
                    self._pipe.stdin.close()
            except OSError:
                pass
            self._pipe.wait()
            self._pipe = None
        if self._log is not None:
            self._log.close()
            self._log = None
        if self._temp is not None:
            self._temp.unlink(missing_ok=True)


def open_writer(path: str | os.PathLike[str], *, fps: float = 24.0,
                kind: OutputKind | None = None, first_frame: int = 0, frames: int = 1) -> FrameWriter:
    """The writer for ``path``, by its suffix (:func:`output_kind`): ``.png`` (one frame),
    a directory of PNG frames, ``.gif`` (1-bit alpha), ``.mp4`` (H.264, no alpha: flattened
    over white), or, with alpha, ``.webm`` (VP9), ``.mov`` (ProRes 4444) and ``.apng``
    (those three from :mod:`inkwarp.outputs`). A sprite sheet is
    :class:`inkwarp.outputs.SpriteSheetWriter`'s (``inkwarp render --sprite-sheet``,
    ``inkwarp.render(..., sprite_sheet=...)``).

    Parameters
    ----------
    path : str or path-like
        The output. Its parent directory must exist.
    fps : float
        Frames per second (the timing of a GIF and of a video), from 0.001 to 1000.
    kind : {"png", "dir", "gif", "mp4", "webm", "mov", "apng"}, optional
        Overrides the guess from the suffix (see :func:`output_kind`).
    first_frame : int
        For a directory: the number of the first frame's file.
    frames : int
        For a directory: how many frames will be written, so that an existing folder that
        cannot take them is refused before any is rendered.

    Returns
    -------
    FrameWriter
        Use it as a context manager; ``writer.paths`` lists the files written.
    """
    kind = kind or output_kind(path)
    target = check_target(path, kind)
    if kind == "png":
        return PngWriter(target, fps)
    if kind == "dir":
        return PngSequenceWriter(target, fps, first_frame, frames)
    if kind == "gif":
        return GifWriter(target, fps)
    if kind == "mp4":
        return Mp4Writer(target, fps)
    if kind in ("webm", "mov", "apng"):
        from inkwarp.outputs import open_writer as open_alpha_writer

        return open_alpha_writer(target, fps=fps, kind=kind)
    raise InputError(f"unknown output kind {kind!r}")


def write_frames(path: str | os.PathLike[str], frames, *, fps: float = 24.0) -> list[Path]:
    """Write an iterable of frames to ``path`` (see :func:`open_writer`); the paths written.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> frames = [np.full((8, 8, 4), v, np.uint8) for v in (0, 255)]
    >>> out = os.path.join(tempfile.mkdtemp(), "frames")
    >>> [p.name for p in write_frames(out, frames, fps=2)]
    ['frame_0000.png', 'frame_0001.png']
    """
    with open_writer(path, fps=fps) as writer:
        for frame in frames:
            writer.write(frame)
    return writer.paths


def field_picture(field: np.ndarray, *, arrows: int = 24, scale_px: float | None = None
                  ) -> np.ndarray:
    """A displacement field as an RGBA picture: colour for direction, strength for length.

    Hue gives the direction a pixel moves (red right, yellow-green down, cyan-blue left,
    purple up: the usual optical-flow wheel) and saturation its length, from white (still)
    to full colour at ``scale_px`` (default: the largest length in the field). Arrows drawn
    every ``arrows`` pixels (0 for none) show the motion at true length.

    Parameters
    ----------
    field : ndarray, shape (H, W, 2)
        ``[..., 0]`` is Δx, ``[..., 1]`` Δy, in pixels.

    Returns
    -------
    ndarray of uint8, shape (H, W, 4)

    Examples
    --------
    >>> f = np.zeros((4, 4, 2), np.float32); f[..., 0] = 1.0   # everything moves right
    >>> field_picture(f, arrows=0)[0, 0].tolist()
    [255, 0, 0, 255]
    """
    from PIL import Image, ImageDraw

    f = np.asarray(field, dtype=np.float64)
    if f.ndim != 3 or f.shape[2] != 2:
        raise InputError(f"a field must have shape (H, W, 2); got {f.shape}")
    f = np.where(np.isfinite(f), f, 0.0)
    dx, dy = f[..., 0], f[..., 1]
    length = np.hypot(dx, dy)
    top = float(scale_px) if scale_px else float(length.max())
    sat = np.clip(length / top, 0.0, 1.0) if top > 0 else np.zeros_like(length)
    hue = (np.arctan2(dy, dx) / (2 * np.pi)) % 1.0  # 0 = right, 1/4 = down (y grows down)
    rgb = _hsv_to_rgb(hue, sat, np.ones_like(sat))
    picture = np.empty(f.shape[:2] + (4,), np.uint8)
    picture[..., :3] = np.round(rgb * 255).astype(np.uint8)
    picture[..., 3] = 255
    if arrows > 0 and top > 0:
        image = Image.fromarray(picture, "RGBA")
        draw = ImageDraw.Draw(image)
        h, w = length.shape
        for y in range(arrows // 2, h, arrows):
            for x in range(arrows // 2, w, arrows):
                ax, ay = dx[y, x], dy[y, x]
                if np.hypot(ax, ay) < 0.5:
                    draw.point((x, y), fill=(60, 60, 60, 255))
                    continue
                _arrow(draw, (x, y), (x + ax, y + ay))
        picture = np.asarray(image).copy()
    return picture


def _arrow(draw, tail: tuple[float, float], head: tuple[float, float]) -> None:
    colour = (40, 40, 40, 255)
    draw.line([tail, head], fill=colour, width=1)
    vx, vy = head[0] - tail[0], head[1] - tail[1]
    n = float(np.hypot(vx, vy))
    size = min(4.0, 0.4 * n)
    ux, uy = vx / n, vy / n
    left = (head[0] - size * (ux - 0.5 * uy), head[1] - size * (uy + 0.5 * ux))
    right = (head[0] - size * (ux + 0.5 * uy), head[1] - size * (uy - 0.5 * ux))
    draw.polygon([head, left, right], fill=colour)


def _hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    i = np.floor(h * 6.0).astype(int) % 6
    f = h * 6.0 - np.floor(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    r = np.choose(i, [v, q, p, p, t, v])
    g = np.choose(i, [t, v, v, q, p, p])
    b = np.choose(i, [p, p, t, v, v, q])
    return np.stack([r, g, b], axis=-1)
