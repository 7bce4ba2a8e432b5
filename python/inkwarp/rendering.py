"""Rendering a scene's frames to any output: in one process, as farm chunks that skip the
frames already written, or spread over a Ray cluster.

Chunks and warm starts. The engine solves frames in warm-start chains of
:data:`WARM_CHAIN_FRAMES` (frames 0, 16, 32, ... start cold, every other frame starts from
the ones before). A range that begins inside a chain first solves that chain's earlier
frames (a pre-roll of at most 15 frames, rendered and dropped: :meth:`inkwarp.Scene.frames`
does it), so every frame of a chunk is the frame a sequential render gives, pixel for
pixel, however a shot is split. Ray
chunks are cut at chain boundaries and need no pre-roll.

Examples
--------
>>> chunk_ranges(0, 100, 3)
[(0, 48), (48, 96), (96, 100)]
>>> preroll_start(37)
32
"""

from __future__ import annotations

import base64
import contextlib
import contextvars
import errno
import math
import mimetypes
import os
import re
import signal
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp.errors import InkwarpWarning, InputError, InternalError, WorkerLostError
from inkwarp.scene import WARM_CHAIN_FRAMES, preroll_start

__all__ = ["WARM_CHAIN_FRAMES", "chunk_ranges", "frame_file_complete", "portable_scene",
           "preroll_start", "ray_workers", "render", "render_range", "warm_starts"]


def warm_starts(scene: Any, method: str | None = None) -> bool:
    """Whether some layer of ``scene`` (with ``method`` instead of the layers' own, if given)
    solves with warm starts, the grid's thin plate (``"tps"``): only then does a frame
    depend on the frames before it, and a range need its pre-roll."""
    return bool(scene._core.warm_starts(method))


def render_range(scene: Any, start: int, stop: int, *, method: str | None = None,
                 threads: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """``(index, frame)`` for frames ``start`` to ``stop - 1`` (those the scene has), each
    exactly as a sequential render of the whole scene gives it (:meth:`inkwarp.Scene.frames`
    solves the pre-roll)."""
    stop = min(stop, scene.frame_count)
    if start >= stop:
        return
    frames = scene.frames(start=start, stop=stop, threads=threads, method=method)
    try:
        yield from enumerate(frames, start)
    finally:
        frames.close()  # stops the engine's workers when the caller stops early


def chunk_ranges(start: int, stop: int, chunks: int) -> list[tuple[int, int]]:
    """``[start, stop)`` cut into about ``chunks`` contiguous ranges at warm-start chain
    boundaries (so no chunk needs a pre-roll beyond the one ``start`` itself needs): one
    more when ``start`` is inside a chain."""
    count = stop - start
    if count <= 0:
        return []
    per = max(1, math.ceil(count / max(1, chunks)))
    per = math.ceil(per / WARM_CHAIN_FRAMES) * WARM_CHAIN_FRAMES
    cuts = [start]
    edge = (start // WARM_CHAIN_FRAMES) * WARM_CHAIN_FRAMES + per
    while edge < stop:
        cuts.append(edge)
        edge += per
    cuts.append(stop)
    return list(zip(cuts[:-1], cuts[1:]))


def portable_scene(scene: Any) -> dict[str, Any]:
    """The scene as a dict whose images are ``data:`` URIs, so that it renders anywhere
    (a Ray worker on another machine) without its files."""
    data = scene.to_dict()
    base = Path(scene.base_dir) if scene.base_dir else Path.cwd()
    for layer in data.get("layers", []):
        for key in ("image", "alpha", "continuity"):
            reference = layer.get(key)
            if reference and not reference.lower().startswith("data:"):
                path = Path(reference) if os.path.isabs(reference) else base / reference
                mime = mimetypes.guess_type(path.name)[0] or "image/png"
                layer[key] = f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode()
    return data


def _background_argument(background: Any) -> list[int]:
    """``[r, g, b, a]`` of a sequence of four integers 0-255, or a ValueError naming the
    argument. Floats are refused, 255.0 included, as a scene's ``background`` refuses them:
    levels 0 to 1 (``[1.0, 1.0, 1.0, 1.0]``) would otherwise pass as almost black."""
    try:
        values = list(background)
    except TypeError:
        values = []
    whole = [isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values]
    if len(values) == 4 and all(whole) and all(0 <= v <= 255 for v in values):
        return [int(v) for v in values]
    fix = "give four integers 0 to 255, [R, G, B, A] (or a colour such as 'transparent' or '#RRGGBB')"
    numbers = [float(v) for v in values if isinstance(v, (int, float, np.integer, np.floating))
               and not isinstance(v, bool)]
    if len(numbers) == len(values) == 4 and not all(whole) and all(0 <= v <= 1 for v in numbers):
        fix += "; for levels 0 to 1, scale them: [round(v * 255) for v in background]"
    raise InputError(f"background={background!r:.80} is not a colour; {fix}")


def _frame_indices(scene: Any, frames: tuple[int, int] | str | None) -> tuple[int, int]:
    from inkwarp.cli._common import parse_frames

    if frames is None:
        return 0, scene.frame_count
    if isinstance(frames, str):
        return parse_frames(frames, scene.frame_count, option="frames")
    from inkwarp.scene import _integer_argument

    if not isinstance(frames, (tuple, list)) or len(frames) != 2:
        raise InputError(f'frames must be (start, stop) or "A:B", got {frames!r:.40}')
    start, stop = (_integer_argument(v, f"frames[{i}]") for i, v in enumerate(frames))
    if not 0 <= start < min(stop, scene.frame_count):
        raise InputError(f"frames=({start}, {stop}) is not a range of the scene, which has frames 0 to "
                         f"{scene.frame_count - 1}; give 0 <= A < B with A < {scene.frame_count}")
    return start, min(stop, scene.frame_count)  # a stop past the end cut to it, as Scene.frames does


#: A PNG file starts with its signature and ends with its IEND chunk (length 0, type, CRC).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def frame_file_complete(path: str | os.PathLike[str], size: tuple[int, int] | None = None) -> bool:
    """Whether ``path`` holds a whole PNG: its signature first and its IEND chunk last,
    and, given ``size`` (width, height), a picture of that size; checked without decoding
    it. A missing, empty or cut-off frame file is not complete, nor one of another size (a
    frame of another render copied there), so ``skip_existing`` renders that frame again.

    Examples
    --------
    >>> import os, tempfile
    >>> path = os.path.join(tempfile.mkdtemp(), "frame_0000.png")
    >>> open(path, "wb").close()
    >>> frame_file_complete(path)
    False
    """
    try:
        with open(path, "rb") as fh:
            if fh.read(len(PNG_SIGNATURE)) != PNG_SIGNATURE:
                return False
            # The IHDR chunk comes first: its length, its name, the width and the height.
            header = fh.read(16)
            width, height = int.from_bytes(header[8:12], "big"), int.from_bytes(header[12:16], "big")
            if size is not None and (header[4:8] != b"IHDR" or (width, height) != size):
                return False
            fh.seek(-len(PNG_END), os.SEEK_END)
            return fh.read(len(PNG_END)) == PNG_END
    except OSError:  # missing, unreadable, a folder, or shorter than a PNG's two ends
        return False


def _write_new_frame(path: Path, frame: np.ndarray) -> bool:
    """Writes ``frame`` to ``path`` unless a complete frame file is there by the time it
    is written (another process's: a farm chunk over the same frames); whether it wrote.
    The file is written under a temporary name and linked into place, which never
    replaces a file, so two processes do not both write one frame; an incomplete file
    there is replaced."""
    from PIL import Image

    from inkwarp._atomic import temp_path
    from inkwarp.imaging import PNG_COMPRESS_LEVEL
    from inkwarp.video import write_failure

    size = (frame.shape[1], frame.shape[0])
    if frame_file_complete(path, size):
        return False
    temp = temp_path(path, ".png")
    try:
        try:
            Image.fromarray(frame, "RGBA").save(temp, format="PNG",
                                                compress_level=PNG_COMPRESS_LEVEL)
        except OSError as err:
            raise write_failure(path, err) from None
        try:
            os.link(temp, path)
            return True
        except OSError as err:
            # Another file there (a whole frame stays; a cut-off one is replaced), or a file
            # system without hard links: checked, then renamed (two chunks that reach the
            # frame at the same moment may both write it, the same bytes).
            if not isinstance(err, FileExistsError) and err.errno not in NO_HARD_LINKS:
                raise write_failure(path, err) from None
        if frame_file_complete(path, size):
            return False
        try:
            os.replace(temp, path)
        except OSError as err:
            raise write_failure(path, err) from None
        return True
    finally:
        temp.unlink(missing_ok=True)


#: The errors of ``os.link`` that mean the file system has no hard links (not a failure).
NO_HARD_LINKS = {errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EXDEV, errno.EMLINK, errno.ENOSYS}


def render(scene: Any, output: str | os.PathLike[str], *, frames: tuple[int, int] | str | None = None,
           method: str | None = None, background: str | list[int] | None = None,
           sprite_sheet: str | bool | None = None, skip_existing: bool = False,
           ray: str | bool | None = None, progress: bool = False) -> list[Path]:
    """Renders a scene's frames to ``output``; the paths written.

    Parameters
    ----------
    scene : inkwarp.Scene or path
        The scene (a path is loaded).
    output : path
        ``.gif``, ``.mp4``, ``.webm``, ``.mov``, ``.apng``, a directory of PNGs, or with
        ``sprite_sheet`` a ``.png`` atlas (and a ``.json`` beside it).
    frames : (start, stop) or "A:B", optional
        Frames ``start`` to ``stop - 1`` (default: all).
    method : str, optional
        The interpolant instead of every layer's ``solver.method``.
    background : str or RGBA list, optional
        ``"transparent"``, a colour (see :func:`inkwarp.outputs.parse_background`), or
        ``[r, g, b, a]``, four integers 0 to 255 as in the scene format, instead of the
        scene's.
    sprite_sheet : True or "COLSxROWS", optional
        Write one atlas PNG with a TexturePacker JSON.
    skip_existing : bool
        For a directory: leave frames whose ``frame_NNNN.png`` is a complete PNG alone (an
        empty or cut-off file is rendered again) and write each new frame atomically as
        soon as it is rendered. Each frame is checked again just before it is rendered and
        written, so a frame that another process (an overlapping farm chunk) wrote
        meanwhile is left as it is; only the paths this call wrote are returned.
    ray : True or address, optional
        Render on a Ray cluster (``True``: the one ``RAY_ADDRESS`` names, else the one
        ``ray start --head`` left running on this machine, else a local one started for
        this render; or an address such as ``"auto"``, ``"HOST:6379"`` or
        ``"ray://HOST:10001"``), in contiguous chunks, one actor per chunk.
    progress : bool
        Show a progress bar on stderr.

    Examples
    --------
    >>> import numpy as np, tempfile, os, inkwarp
    >>> art = np.zeros((16, 16, 4), np.uint8); art[4:12, 4:12] = (0, 0, 255, 255)
    >>> scene = inkwarp.Scene.from_dict({"inkwarp": 1, "fps": 4, "duration": 1,
    ...     "layers": [{"name": "a", "image": inkwarp.image_data_uri(art)}]})
    >>> out = os.path.join(tempfile.mkdtemp(), "frames")
    >>> [p.name for p in inkwarp.render(scene, out, frames=(1, 3))]
    ['frame_0001.png', 'frame_0002.png']
    """
    from inkwarp import outputs, video
    from inkwarp.cli import _common

    if not isinstance(output, (str, os.PathLike)):
        raise InputError(f"the output must be a path (a video file, a folder of PNGs or a sprite sheet); "
                         f"got {type(output).__name__}")
    if not hasattr(scene, "frames"):
        if not isinstance(scene, (str, os.PathLike)):
            raise InputError(f"the scene must be an inkwarp.Scene or the path of a scene file; "
                             f"got {type(scene).__name__}")
        if sprite_sheet:
            outputs.check_sheet_json(output, scene)
        scene = _common.load_scene(os.fspath(scene))
    elif sprite_sheet:
        # A loaded scene: its own file (if it came from one), or any other JSON there.
        outputs.check_sheet_json(output, getattr(scene, "file", None))
    if background is not None:
        colour = (outputs.parse_background(background, option="background")
                  if isinstance(background, str)
                  else _background_argument(background))
        scene = outputs.with_background(scene, colour)
    start, stop = _frame_indices(scene, frames)
    kind = video.output_kind(output)
    target = video.check_target(output, kind)
    # Never over the scene's own files (its pictures as it holds them): the output itself,
    # or, for a folder, the frames written into it.
    if kind == "dir":
        outputs.check_frames_not_inputs(target, start, stop, scene)
    else:
        outputs.check_not_an_input(target, scene)
    if sprite_sheet:
        if target.suffix.lower() != ".png":
            raise InputError(f"{target}: a sprite sheet is a .png (with a .json beside it); "
                             "name the output sheet.png")
        layout = None if sprite_sheet is True else str(sprite_sheet)
        # A bad layout, or a sheet too big to load, fails before rendering.
        size = (scene.width, scene.height)
        outputs.check_sheet_size(*outputs.sheet_layout(stop - start, layout, "sprite_sheet", size),
                                 scene.width, scene.height, layout, "sprite_sheet")
        writer: Any = outputs.SpriteSheetWriter(target, scene.fps, stop - start, layout, start, size)
    elif kind == "png":
        raise InputError(f"{target}: a .png holds one frame (save Scene.render(time=T) for one; "
                         "inkwarp render --time or --frame); render an animation to a .gif, "
                         ".mp4, .webm, .mov, .apng, a directory, or a sprite sheet "
                         "(sprite_sheet=True; inkwarp render --sprite-sheet)")
    elif skip_existing:
        if kind != "dir":
            raise InputError(f"{target}: skip_existing=True works with a directory of PNG "
                             "frames (an output ending in /), whose frames are separate files")
        written = _render_missing(scene, target, start, stop, method=method, ray=ray,
                                  progress=progress)
        _note_frames_past_the_end(target, stop, scene.frame_count)
        return written
    else:
        writer = outputs.open_writer(target, fps=scene.fps, kind=kind, first_frame=start,
                                     frames=stop - start)
    count = stop - start
    source = (_ray_frames(scene, start, stop, method=method, address=ray, progress=progress)
              if ray else _common.progress((f for _, f in render_range(scene, start, stop,
                                                                       method=method)),
                                           count, quiet=not progress,
                                           desc=f"render {target.name or target}"))
    with writer, contextlib.closing(source):  # (closed first: see _render_missing)
        for frame in source:
            writer.write(frame)
        if writer.frames_written != count:
            raise RuntimeError(f"the scene gave {writer.frames_written} frames for {start}:{stop}")
    if kind == "dir":
        _note_frames_past_the_end(target, stop, scene.frame_count)
    return writer.paths


def _note_frames_past_the_end(folder: Path, stop: int, frame_count: int) -> None:
    """Warns where a render that reached the scene's last frame leaves frame files past it
    in ``folder`` (an earlier, longer render's): a join of the folder's frames would take
    them too."""
    from inkwarp.errors import InkwarpWarning, caller_outside
    from inkwarp.video import FRAME_PATTERN

    after = folder / FRAME_PATTERN.format(frame_count)
    if stop == frame_count and after.exists():
        warnings.warn(f"{folder}: {after.name} and maybe more, from an earlier render, lie past this scene's "
                      f"last frame ({frame_count - 1}); delete them before joining the folder's frames",
                      InkwarpWarning, stacklevel=caller_outside())


def _render_missing(scene: Any, target: Path, start: int, stop: int, *, method: str | None,
                    ray: str | bool | None, progress: bool) -> list[Path]:
    from inkwarp import _atomic, video
    from inkwarp.cli import _common

    target.mkdir(exist_ok=True)
    # A whole-folder render of this output killed half-way left its hidden folder beside it.
    _atomic.clean_stale(target)
    names = {i: target / video.FRAME_PATTERN.format(i) for i in range(start, stop)}
    size = (scene.width, scene.height)
    missing = [i for i in range(start, stop) if not frame_file_complete(names[i], size)]
    written: list[Path] = []
    if not missing:
        return written
    if ray:
        _ray_init(ray, chatter=progress)  # its chunks' runs below join quietly

    def frames() -> Iterator[tuple[int, np.ndarray | None]]:
        """``(index, frame)`` for each missing frame, or ``(index, None)`` for one that
        another process wrote meanwhile. Each frame is checked again just before it is
        rendered: a run that meets a frame written meanwhile stops there and starts again
        (with its pre-roll) at the next frame still missing. Ray chunks run on: their
        frames are checked just before they are written."""
        pos = 0
        while pos < len(missing):
            a = missing[pos]
            if not ray and frame_file_complete(names[a], size):
                yield a, None
                pos += 1
                continue
            b = a + 1
            while pos + (b - a) < len(missing) and missing[pos + (b - a)] == b:
                b += 1
            source = (_indexed(a, _ray_frames(scene, a, b, method=method, address=ray,
                                              progress=False)) if ray
                      else render_range(scene, a, b, method=method))
            try:
                for index, frame in source:
                    pos += 1
                    yield index, frame
                    if not ray and index + 1 < b and frame_file_complete(names[index + 1], size):
                        break
            finally:
                source.close()

    # Closed as the loop ends, however: a progress display left to the garbage collector
    # printed its last line after the command's "interrupted".
    with contextlib.closing(_common.progress(frames(), len(missing), quiet=not progress,
                                             desc=f"render {target.name}")) as shown:
        for index, frame in shown:
            if frame is not None and _write_new_frame(names[index], frame):
                written.append(names[index])
    return written


def _indexed(start: int, frames: Iterator[np.ndarray]) -> Iterator[tuple[int, np.ndarray]]:
    """``(index, frame)`` of ``frames`` numbered from ``start``; closing it closes them."""
    try:
        yield from enumerate(frames, start)
    finally:
        frames.close()  # type: ignore[attr-defined]


# ---- Ray ---------------------------------------------------------------------------------

#: How many frames an actor sends at a time, and how far one may run ahead of the writer.
RAY_BATCH_FRAMES = 4
RAY_AHEAD_FRAMES = 32
#: Times a chunk is started again on a new actor after its worker died (killed for memory,
#: its node lost) before the render stops.
RAY_RESTARTS = 2


#: How messages name the Ray option: the Python argument (``ray=``), or ``--ray`` while the
#: command line renders.
RAY_OPTION: contextvars.ContextVar[str] = contextvars.ContextVar("ray_option", default="ray=")


def _ray_said(address: str | bool | None = None) -> str:
    """The Ray option as given (``--ray HOST:PORT``, ``ray='HOST:PORT'``); without an address,
    the option alone, and ``True`` as the option that starts or finds a cluster."""
    cli = RAY_OPTION.get() == "--ray"
    if address is None:
        return "--ray" if cli else "ray="
    if address is True:
        return "--ray without an address" if cli else "ray=True"
    return f"--ray {address}" if cli else f"ray={address!r}"


def _check_address(address: str, where: str | None = None, fix: str | None = None) -> None:
    """A quick connection test, so that an address nobody answers at fails in seconds
    with a clear message instead of Ray's long retries. Messages start with ``where`` (the
    option that gave the address) and say ``fix`` where nothing answers."""
    import socket

    where = where or _ray_said(address)

    if address in ("auto", "local"):
        return
    text = address.split("://", 1)[-1]
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise InputError(f"{where}: give the cluster's address as HOST:PORT (such as "
                         "10.0.0.5:6379), ray://HOST:PORT, or auto")
    if not 0 < int(port) < 65536:
        raise InputError(f"{where}: {port} is not a port (ports run from 1 to 65535); give the "
                         "port 'ray status' prints on the head node (6379 unless it was started with another)")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=5) as conn:
            reply = _http2_reply(conn)
    except OSError as err:
        raise InputError(f"{where}: no Ray cluster answers there ({err.strerror or err}); " + (
            fix or "start one with 'ray start --head' (or 'ray up cluster.yaml') and give its "
            "address, or leave the address out to start a local one")) from None
    # Ray's head (and its client server) speak gRPC: HTTP/2, which answers the connection
    # preface with a SETTINGS frame. Anything else (a web server on a mistyped port) left
    # Ray retrying without end. Under TLS (RAY_USE_TLS) the preface is not spoken in clear.
    tls = os.environ.get("RAY_USE_TLS", "").lower() in ("1", "true")
    if not tls and (len(reply) < 4 or reply[3] != 4):
        said = (reply.splitlines() or [b"nothing"])[0].decode("latin-1")[:60]
        raise InputError(f"{where}: something answers there, but not a Ray cluster (it "
                         f"replied {said!r}); give the address 'ray status' prints on the head "
                         "node (port 6379 unless it was started with another)")


def _left_by_ray_start() -> str | None:
    """The address `ray start --head` last wrote on this machine (``ray_current_cluster``
    in Ray's temporary folder), which ``ray.init()`` without an address joins."""
    import tempfile

    unix = sys.platform.startswith(("linux", "darwin"))
    base = (os.environ.get("RAY_TMPDIR") or (sys.platform.startswith("linux") and os.environ.get("TMPDIR"))
            or ("/tmp" if unix else tempfile.gettempdir()))
    try:
        return (Path(base) / "ray" / "ray_current_cluster").read_text().strip() or None
    except OSError:
        return None


def _http2_reply(conn: Any) -> bytes:
    """The first bytes a server sends back to an HTTP/2 connection preface (within 5 s)."""
    import socket

    try:
        conn.sendall(b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0]))
        return conn.recv(64)
    except (socket.timeout, ConnectionError):
        return b""


@contextlib.contextmanager
def _stderr_held() -> Iterator[list[str]]:
    """What this process (Ray's C++ core included) writes to file descriptor 2 meanwhile,
    and to ``sys.stderr`` (where Ray's Python warnings go, which in a notebook is not fd 2),
    held back and handed over in the list yielded, instead of printed. Under
    ``RAY_LOG_TO_STDERR`` nothing is held: Ray's processes started meanwhile keep fd 2 as
    their log, which must stay the terminal."""
    held: list[str] = []
    if os.environ.get("RAY_LOG_TO_STDERR"):
        held.append("")
        yield held
        return
    import io
    import tempfile

    sys.stderr.flush()
    said, shown = io.StringIO(), sys.stderr
    with tempfile.TemporaryFile() as sink:
        saved = os.dup(2)
        try:
            os.dup2(sink.fileno(), 2)
            sys.stderr = said
            yield held
        finally:
            sys.stderr = shown
            os.dup2(saved, 2)  # the terminal back first, whatever else fails
            os.close(saved)
            sink.seek(0)
            held.append(said.getvalue() + sink.read().decode("utf-8", "replace"))


def _ray_init(address: str | bool | None, chatter: bool = False) -> Any:
    """Ray, joined to the cluster at ``address`` (a local one started for ``True``). Ray's
    own start-up lines are shown only with ``chatter`` (not under ``-q``) or when a local
    start fails, and not when joining a cluster fails: the error says what to do."""
    try:
        import ray
    except ImportError:
        raise InputError(f"{_ray_said()} needs Ray: install it with 'pip install \"inkwarp[ray]\"'"
                         ) from None
    local = address is True or address in (None, "", "local")
    if not local:
        _check_address(str(address))
    _ray_notices_to_stderr()
    if ray.is_initialized():
        return ray
    with _sigterm_kept():
        _ray_join(ray, address, local, chatter)
    return ray


def ray_shutdown() -> None:
    """Leaves the Ray cluster a render joined or started (stopping a local one), Ctrl-C held
    off meanwhile (not SIGTERM: a farm cancelling a job whose cluster hangs is obeyed). Left
    to Ray's own shutdown at the interpreter's exit, a Ctrl-C there printed a traceback and
    left the local cluster's processes running."""
    ray = sys.modules.get("ray")
    if ray is None or not ray.is_initialized():
        return
    held = None
    with contextlib.suppress(ValueError):  # (signals are set from the main thread only)
        held = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        ray.shutdown()
    finally:
        if held is not None:
            signal.signal(signal.SIGINT, held)


def _ray_notices_to_stderr() -> None:
    """Sends the notices Ray's nodes give a driver (``(raylet) A worker died or was killed
    ...``, ``(raylet) ... memory ...``) to stderr, as plain lines where stderr is no
    terminal: Ray's driver prints them on stdout, in colour, from a thread that listens to
    its error channel (``ray._private.worker.listen_error_messages`` calls the module's
    ``print_to_stdstream`` with ``is_err`` False), even under ``log_to_driver=False``; and
    the command line's stdout holds its summary line only. The workers' own output (under
    ``log_to_driver``) goes where Ray sends it. Done once per process, for every Ray
    session in it; a Ray without that function is left as it is."""
    try:
        from ray._private import worker
    except ImportError:
        return
    printer = getattr(worker, "print_to_stdstream", None)
    if printer is None or getattr(printer, "_inkwarp_original", None) is not None:
        return

    def print_to_stdstream(data: Any, ignore_prefix: bool) -> Any:
        if not (isinstance(data, dict) and data.get("pid") == "raylet" and not data.get("is_err")):
            return printer(data, ignore_prefix)
        plain = not getattr(sys.stderr, "isatty", lambda: False)()
        for line in data.get("lines") or []:
            text = _ANSI.sub("", str(line)) if plain else str(line)
            sys.stderr.write(f"(raylet) {text}\n")
        sys.stderr.flush()
        return None

    print_to_stdstream._inkwarp_original = printer  # type: ignore[attr-defined]
    worker.print_to_stdstream = print_to_stdstream


#: ANSI colour and style codes, which Ray's notices may carry.
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


@contextlib.contextmanager
def _sigterm_kept() -> Iterator[None]:
    """Keeps the SIGTERM and SIGHUP handlers of the command line: joining Ray installs Ray's
    own (one that exits with status 1, and one in its core that prints a crash dump), so a
    render a farm's scheduler cancelled left no word of its own and an exit status that said
    it crashed."""
    import signal
    import threading

    from inkwarp.cli._common import UNWINDING

    handlers = {number: signal.getsignal(number) for number in UNWINDING}
    try:
        yield
    finally:
        # (A handler of the caller's own, as the command line's; Python's default gives way to Ray's.)
        if threading.current_thread() is threading.main_thread():
            for number, handler in handlers.items():
                if callable(handler) or handler is signal.SIG_IGN:  # (nohup's SIGHUP stays ignored)
                    signal.signal(number, handler)


@contextlib.contextmanager
def _signals_raised() -> Iterator[None]:
    """A signal's exception (SIGTERM's, Ctrl-C's) raised inside Ray's core comes out as a
    SystemError around it: the signal's own goes on, to end the command as the signal does."""
    try:
        yield
    except SystemError as err:
        if isinstance(err.__context__, BaseException) and not isinstance(err.__context__, Exception):
            raise err.__context__ from None
        raise


def _descendants() -> set[int]:
    """The process ids of this process's children and theirs, from ``/proc`` (none where
    there is no ``/proc``, as on macOS: there an interrupted start leaves Ray's agents to
    stop on their own, about a minute later)."""
    children: dict[int, list[int]] = {}
    with contextlib.suppress(OSError):
        for entry in os.scandir("/proc"):
            with contextlib.suppress(OSError, ValueError, IndexError):
                with open(f"/proc/{entry.name}/stat", "rb") as stat:  # "pid (name) state ppid ..."
                    children.setdefault(int(stat.read().rsplit(b")", 1)[1].split()[1]), []).append(int(entry.name))
    found, todo = set(), [os.getpid()]
    while todo:
        for pid in children.get(todo.pop(), []):
            if pid not in found:
                found.add(pid)
                todo.append(pid)
    return found


def _ray_join(ray: Any, address: str | bool | None, local: bool, chatter: bool) -> None:
    """``ray.init`` for :func:`_ray_init`."""
    if local:
        # Ray joins the cluster RAY_ADDRESS names, else the one `ray start --head` last left
        # on this machine, and where that has gone (stopped by a kill, or crashed) it retried
        # without end: RAY_ADDRESS is checked as an address given is, and a cluster gone is
        # passed over for one started here.
        target, named = None, os.environ.get("RAY_ADDRESS")
        if named:
            _check_address(named, f"RAY_ADDRESS={named}, the cluster {_ray_said(True)} joins",
                           "start it, or unset RAY_ADDRESS to start a local one")
        elif (left := _left_by_ray_start()) is not None:
            try:
                _check_address(left)
            except ValueError:
                target = "local"
        said: list[str] = []
        before = _descendants()
        try:
            with _stderr_held() as said:
                ray.init(address=target, include_dashboard=False, log_to_driver=False, configure_logging=False)
        except BaseException as err:
            if isinstance(err, Exception):
                sys.stderr.write("".join(said))  # Ray's own account of a local start that failed
            # What had started of the cluster stops with it: interrupted before Ray knew its
            # processes, its agents ran on for a minute after this process ended.
            started = _descendants() - before
            try:
                with contextlib.suppress(Exception):
                    ray.shutdown()
            finally:  # (a second Ctrl-C too)
                for pid in started:
                    with contextlib.suppress(OSError):
                        os.kill(pid, signal.SIGTERM)
            raise
        if chatter:
            sys.stderr.write(said[0])
    else:
        try:
            with _stderr_held() as said:
                ray.init(address=str(address), log_to_driver=False, configure_logging=False)
            if chatter:
                sys.stderr.write(said[0])
        except (ConnectionError, RuntimeError, TimeoutError) as err:
            # A head started where Ray keeps a token (~/.ray/auth_token) asks for it, which
            # this process sends only under RAY_AUTH_MODE=token; Ray says so only in its log.
            token = not os.environ.get("RAY_AUTH_MODE") and (Path.home() / ".ray" / "auth_token").exists()
            hint = "; or, since this machine has a Ray token (~/.ray/auth_token), set RAY_AUTH_MODE=token" if token else ""
            raise InputError(f"{_ray_said(address)}: cannot join the Ray cluster there ({err}); "
                             f"check the address 'ray status' prints on the head node{hint}") from None


def ray_workers(nodes: list[dict[str, Any]], need: int) -> int:
    """How many render workers of one CPU and ``need`` bytes the live Ray nodes hold at
    once (``nodes`` as ``ray.nodes()`` gives them): on each node the fewer of its CPUs and
    its memory for tasks over ``need``. So a scene whose layers keep large solvers runs on
    fewer workers than there are CPUs instead of running out of memory; a scene that no
    node has the memory for is refused with the fix."""
    slots, largest, alive = 0, 0.0, False
    for node in nodes:
        if not node.get("Alive", True):
            continue
        resources = node.get("Resources", {})
        memory = float(resources.get("memory", 0.0))
        largest, alive = max(largest, memory), True
        slots += min(int(resources.get("CPU", 0)), int(memory // max(need, 1)))
    if not alive:
        raise InputError("the Ray cluster has no live node to render on; start one "
                         "('ray start --address=HEAD_IP:6379') and render again")
    if slots == 0:
        size = lambda b: f"{b / (1 << 30):.1f} GiB" if b >= 1 << 30 else f"{b / (1 << 20):.0f} MiB"
        raise InputError(
            f"rendering this scene needs one CPU and about {size(need)} of memory a worker, but "
            f"no live Ray node has both (the largest has {size(largest)} for tasks); use a "
            "larger solver.grid_step, fewer layers or a smaller picture")
    return slots


class _ChunkRenderer:
    """One Ray actor: renders its contiguous chunk in order, keeping its warm start."""

    def __init__(self, doc: dict[str, Any], start: int, stop: int, method: str | None) -> None:
        from inkwarp.scene import Scene

        # One chain at a time: the actor has one CPU and one render's memory.
        self._frames = render_range(Scene.from_dict(doc), start, stop, method=method, threads=1)

    def next_batch(self, count: int) -> tuple[list[np.ndarray], list[tuple[type[Warning], str]]]:
        """Up to ``count`` frames, and the inkwarp warnings their solves gave (a solve that
        did not converge): ``(category, message)``, for the caller to give again."""
        batch = []
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", InkwarpWarning)
            for _ in range(count):
                item = next(self._frames, None)
                if item is None:
                    break
                batch.append(item[1])
        return batch, [(w.category, str(w.message)) for w in said if issubclass(w.category, InkwarpWarning)]


def _ray_frames(scene: Any, start: int, stop: int, *, method: str | None,
                address: str | bool | None, progress: bool) -> Iterator[np.ndarray]:
    """Frames ``start`` to ``stop - 1`` rendered by Ray actors, one per contiguous chunk,
    yielded in order; one progress bar counts the frames of every actor. At most as many
    actors run at once as the cluster holds (:func:`ray_workers`); each one ends with its
    chunk, and the next chunk's starts in its place."""
    ray = _ray_init(address, chatter=progress)
    need = scene.render_bytes
    workers = ray_workers(ray.nodes(), need)
    chunks = chunk_ranges(start, stop, workers)
    doc = ray.put(portable_scene(scene))
    # Each actor gets one CPU (its solver uses that many threads) and the scene's memory.
    Actor = ray.remote(num_cpus=1, memory=need,
                       runtime_env={"env_vars": {"RAYON_NUM_THREADS": "1"}})(_ChunkRenderer)
    actors: dict[int, Any] = {}  # by chunk, the chunks started and not finished
    started = 0
    remaining = [b - a for a, b in chunks]
    restarts = [0 for _ in chunks]
    buffers: list[list[np.ndarray]] = [[] for _ in chunks]
    pending: dict[Any, int] = {}
    lost = (ray.exceptions.RayActorError, ray.exceptions.WorkerCrashedError, ray.exceptions.ObjectLostError)

    def launch() -> None:
        nonlocal started
        while len(actors) < workers and started < len(chunks):
            actors[started] = Actor.remote(doc, *chunks[started], method)
            started += 1

    def ask(i: int) -> None:
        if i in actors and remaining[i] > 0 and i not in pending.values():
            pending[actors[i].next_batch.remote(RAY_BATCH_FRAMES)] = i

    def ask_running() -> None:
        # The current chunk always; the others while they are not too far ahead.
        for i in list(actors):
            if i == current or len(buffers[i]) < RAY_AHEAD_FRAMES:
                ask(i)

    bar = None
    if progress:
        from inkwarp.cli._common import progress_bar

        bar = progress_bar(stop - start, f"render on Ray ({len(chunks)} chunk{'s' if len(chunks) != 1 else ''})")
    current = 0
    try:
        launch()
        ask_running()
        while current < len(chunks):
            if buffers[current]:
                yield buffers[current].pop(0)
                if remaining[current] == 0 and not buffers[current]:
                    current += 1
                ask_running()
                continue
            if remaining[current] == 0:
                current += 1
                continue
            with _signals_raised():
                ready, _ = ray.wait(list(pending), num_returns=1)
            i = pending.pop(ready[0])
            try:
                with _signals_raised():
                    batch, said = ray.get(ready[0])
            except lost as err:
                # Its worker died: the chunk's frames not yet received on a new actor. One
                # that could not start (the scene or inkwarp missing on a node) would fail
                # again: its reason is said at once.
                first, end = chunks[i][1] - remaining[i], chunks[i][1]
                said = [line.strip() for line in str(err).splitlines() if line.strip()]
                why = f"{type(err).__name__}: {_sentences(said[-1], 160) if said else 'no reason given'}"
                if getattr(err, "actor_init_failed", False):
                    raise WorkerLostError(f"the Ray worker for frames {first}:{end} could not start ({why}); "
                                          "check that every node has inkwarp and the scene's files") from None
                restarts[i] += 1
                if restarts[i] > RAY_RESTARTS:
                    raise WorkerLostError(
                        f"the Ray worker rendering frames {first}:{end} died {restarts[i]} time{'s' if restarts[i] > 1 else ''} ({why}); give "
                        "the cluster more memory, or render to a folder (-o DIR/ --skip-existing) and run "
                        "again to resume") from None
                warnings.warn(f"the Ray worker rendering frames {first}:{end} died ({why}); rendering them "
                              "on a new one", InkwarpWarning, stacklevel=2)
                _kill(ray, actors[i])
                actors[i] = Actor.remote(doc, first, end, method)
                ask_running()
                continue
            if not batch:
                raise InternalError(f"internal error: the Ray actor of frames {chunks[i][0]}:{chunks[i][1]} "
                                    f"stopped with {remaining[i]} frames to go; this is a bug in inkwarp, "
                                    "please report it")
            # The workers' warnings (a solve that did not converge), given here as if solved here.
            for category, text in said:
                warnings.warn(text, category, stacklevel=2)
            buffers[i].extend(batch)
            remaining[i] -= len(batch)
            if bar is not None:
                bar.update(len(batch))
            if remaining[i] == 0:  # its CPU and memory go to the next chunk
                ray.kill(actors.pop(i))
                launch()
            ask_running()
    finally:
        if bar is not None:
            bar.close()
        for actor in actors.values():
            _kill(ray, actor)


def _sentences(text: str, most: int) -> str:
    """The first sentences of ``text`` within ``most`` characters (at least the first, cut)."""
    if len(text) <= most:
        return text
    end = text.rfind(". ", 0, most)
    return text[:end + 1] if end > 0 else text[:most] + "..."


def _kill(ray: Any, actor: Any) -> None:
    try:
        ray.kill(actor)
    except Exception:  # noqa: BLE001 - an actor already gone
        pass
