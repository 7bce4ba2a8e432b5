"""``inkwarp edit [SCENE]``: serve the browser editor on this machine and open it.

The editor is a static web application shipped inside the package (``inkwarp/editor/``,
built from ``web/`` by ``make editor``). This command serves it on 127.0.0.1 at a free
port. Given a scene, it also serves ``/api/scene``: the scene with its images inlined as
``data:`` URIs (GET), each one's path as the scene file names it beside it (the header
``X-Inkwarp-Pictures``, for the editor's messages), and a way to save it back (PUT) — images
that came from files keep their relative paths when the scene is written back, new ones stay
inline.

Every GET and PUT answers the file's version (``ETag``: a hash of its text); a PUT that
carries ``If-Match`` with another version is refused (409), so a save never overwrites
what another tab or program wrote to the file since the editor read it. ``/api/scene/version``
answers the version alone, which a tab asks for every few seconds: a scene marked saved
whose file another writer changed is marked unsaved again. Both answer each picture's stamp
(``X-Inkwarp-Stamps``: inode, size and modification time), so a tab tells a picture
retouched by another program since it opened it.
"""

from __future__ import annotations

import argparse
import base64
import errno
import hashlib
import hmac
import json
import mimetypes
import os
import secrets
import socket
import stat
import sys
import threading
import webbrowser
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, quote, unquote, urlsplit

IMAGE_KEYS = ("image", "alpha", "continuity")
MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
#: The magic numbers of the pictures the server inlines; nothing else is ever read.
IMAGE_MAGIC = (b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff")

#: The largest scene a save may send (images inline as data: URIs count).
MAX_BODY_BYTES = 64 * 1024 * 1024
#: Seconds a connection may sit idle mid-request before the server drops it.
SOCKET_TIMEOUT_S = 10.0
#: Requests handled at once; more are answered 503 at once instead of tying up a thread.
MAX_WORKERS = 16
#: The page's Content-Security-Policy: its own scripts, WebAssembly and workers, pictures
#: from data: and blob: URIs, nothing from elsewhere and no framing.
CSP = ("default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; worker-src 'self' blob:; "
       "img-src 'self' data: blob:; media-src 'self' data: blob:; connect-src 'self' data: blob:; "
       "style-src 'self' 'unsafe-inline'; font-src 'self' data:; object-src 'none'; "
       "base-uri 'none'; form-action 'none'; frame-ancestors 'none'")
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")


def editor_dir() -> Path:
    """Where the built editor is (``INKWARP_EDITOR_DIR`` overrides, for development)."""
    override = os.environ.get("INKWARP_EDITOR_DIR")
    if override:
        return Path(override)
    return Path(__file__).resolve().parent.parent / "editor"


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
    except ValueError:
        return False
    return True


def _check_decodes(data: bytes, where: str) -> None:
    """Refuse a picture that does not decode (cut short, damaged), naming its file at
    ``where``: inlined as it is, the editor could name only its data: URI."""
    import io
    import warnings

    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a large picture is the scene's limits' matter
            with Image.open(io.BytesIO(data)) as picture:
                picture.load()
    except (Image.DecompressionBombError, MemoryError):
        return  # not damaged: too large, which the scene's own checks say
    except Exception as err:  # PIL raises OSError, SyntaxError, ValueError, ... for bad bytes
        raise ValueError(f"{where}: the picture could not be decoded ({err}): the file is damaged or "
                         "cut short; save it again") from None


class SceneFile:
    """A scene on disk as the editor sees it: images inlined, and written back with paths.

    Only pictures in the scene's folder (or below it), or named by the scene file as it was
    when the server started, are ever read; a path a request names outside them is refused.

    Parameters
    ----------
    path : pathlib.Path
        The scene file.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.folder = path.resolve().parent
        # Each inlined picture's data: URI and the paths it came from (two files with the
        # same bytes share one), with the layer name, index and key each was read at.
        self.inlined: dict[str, list[tuple[str, Any, int, str]]] = {}
        # A save's check of the file's version and its write happen together.
        self.lock = threading.Lock()
        self._version: tuple[tuple[int, int, int], str] | None = None
        # Each picture a read inlined, by the path the scene names it by: its file and stamp then.
        self.pictures: dict[str, tuple[Path, str]] = {}
        # The images the user's own file names (such as ../cat/cat.png) stay readable.
        self.trusted: set[Path] = set()
        try:
            doc = json.loads(path.read_text(encoding="utf-8-sig"))
        except (OSError, ValueError):
            doc = None
        for _, _, ref in self._image_refs(doc):
            self.trusted.add((self.folder / ref).resolve())

    @staticmethod
    def _image_refs(doc: Any):
        layers = doc.get("layers", []) if isinstance(doc, dict) else []
        for i, layer in enumerate(layers if isinstance(layers, list) else []):
            if not isinstance(layer, dict):
                continue
            for key in IMAGE_KEYS:
                ref = layer.get(key)
                if isinstance(ref, str) and not ref.startswith("data:"):
                    yield i, key, ref

    def image_file(self, i: int, key: str, ref: str) -> Path:
        """The file an image path names, if the server may read it (else ``ValueError``)."""
        where = f"{self.path}: layers[{i}].{key}"
        if "\0" in ref:
            raise ValueError(f"{where}: the image path {ref!r} holds a NUL character.")
        file = (self.folder / ref).resolve()
        if not (_inside(file, self.folder) or file in self.trusted):
            raise ValueError(f"{where}: the image {ref!r} is outside the scene's folder "
                             f"{self.folder}; copy it there, or embed it as a data: URI.")
        if file.suffix.lower() not in MIME:
            raise ValueError(f"{where}: the image {ref!r} is not a .png, .jpg or .jpeg file.")
        try:
            st = file.stat()
        except OSError:
            raise ValueError(f"{where}: the image {ref!r} does not exist.") from None
        if not stat.S_ISREG(st.st_mode):
            raise ValueError(f"{where}: the image {ref!r} is not a regular file.")
        return file

    @staticmethod
    def stamp(file: Path) -> str:
        """A picture file's stamp, new whenever another program writes it (inode, size and
        modification time); empty where it cannot be read."""
        try:
            st = file.stat()
        except OSError:
            return ""
        return f"{st.st_ino:x}.{st.st_size:x}.{st.st_mtime_ns:x}"

    def stamps(self) -> dict[str, str]:
        """The stamp of every picture a read inlined, as its file is now."""
        return {ref: self.stamp(file) for ref, (file, _) in self.pictures.items()}

    @staticmethod
    def version_of(text: str) -> str:
        """The version of a scene file's text, as the ``ETag`` the editor sends back."""
        return '"' + hashlib.sha256(text.encode("utf-8")).hexdigest()[:24] + '"'

    def version(self, cached: bool = False) -> str | None:
        """The version of the file as it is now (None when it cannot be read). ``cached``: read
        and hashed again only where its inode, size or modification time changed (for the tabs'
        checks every few seconds, as a scene with inlined pictures can be tens of MiB; never
        for a save's check, which two quick writes of one size could fool)."""
        from inkwarp.scene import read_scene_text

        try:
            st = os.stat(self.path)
            key = (st.st_ino, st.st_size, st.st_mtime_ns)
            if cached and self._version is not None and self._version[0] == key:
                return self._version[1]
            version = self.version_of(read_scene_text(self.path))
            self._version = (key, version)
            return version
        except (OSError, ValueError):
            return None

    def read(self) -> tuple[bytes, str, dict[str, str]]:
        """The scene as JSON with every relative image path replaced by a data: URI, the
        version of the file's text it was made from, and the path each data: URI replaced,
        by its place (``{"0.image": "art/cat.png"}``)."""
        from inkwarp.scene import _repeated_keys, read_scene_text

        # The scene files' one reader: a picture given as the scene, bytes that are not
        # UTF-8 and oversized files get the messages every command gives.
        text = read_scene_text(self.path)
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as err:
            raise ValueError(
                f"{self.path}: not valid JSON (line {err.lineno}, column {err.colno}: {err.msg})."
            ) from None
        # A key given twice would lose one of its values at the first save.
        repeated = _repeated_keys(text)
        if repeated:
            where, message = repeated[0]
            raise ValueError(f"{self.path}: {where}: {message}.")
        files: dict[str, str] = {}
        for i, key, ref in list(self._image_refs(doc)):
            file = self.image_file(i, key, ref)
            self.pictures[ref] = (file, self.stamp(file))  # taken before the bytes: a change while reading is told
            data = file.read_bytes()
            if not data.startswith(IMAGE_MAGIC):
                raise ValueError(f"{self.path}: layers[{i}].{key}: {ref!r} is not a PNG or JPEG "
                                 "picture.")
            _check_decodes(data, f"{self.path}: layers[{i}].{key}: cannot use {ref!r}")
            mime = MIME.get(file.suffix.lower()) or mimetypes.guess_type(file.name)[0] or "image/png"
            uri = f"data:{mime};base64," + base64.b64encode(data).decode("ascii")
            froms, entry = self.inlined.setdefault(uri, []), (ref, doc["layers"][i].get("name"), i, key)
            if entry in froms:
                froms.remove(entry)
            froms.append(entry)  # the latest read last
            doc["layers"][i][key] = uri
            files[f"{i}.{key}"] = ref
        return json.dumps(doc).encode("utf-8"), self.version_of(text), files

    def _named_now(self, layer: dict, i: int, key: str) -> str | None:
        """The path the scene file names now for this key of the same-named layer (else of
        the layer at the same place), or None where it names none."""
        try:
            doc = json.loads(self.path.read_text(encoding="utf-8-sig"))
        except (OSError, ValueError):
            return None
        layers = doc.get("layers") if isinstance(doc, dict) else None
        layers = [x for x in layers if isinstance(x, dict)] if isinstance(layers, list) else []
        same = [x for x in layers if x.get("name") == layer.get("name")] or layers[i:i + 1]
        ref = same[0].get(key) if same else None
        return ref if isinstance(ref, str) and not ref.startswith("data:") else None

    def _kept_copies(self, doc: dict, kept: list[tuple[int, str]]) -> list[tuple[int, str, bytes, str, str]]:
        """The kept copies the editor marks (a picture of this file's that was changed on
        disk since the work was kept): ``(layer, key, bytes, new path, old path)`` for each
        that is no longer the file's picture; one still the same goes back to its path."""
        layers = doc.get("layers", [])
        planned: list[tuple[int, str, bytes, str, str]] = []
        taken: set[Path] = set()
        for i, key in kept:
            layer = layers[i] if isinstance(layers, list) and 0 <= i < len(layers) else None
            uri = layer.get(key) if isinstance(layer, dict) and key in IMAGE_KEYS else None
            ref = self._named_now(layer, i, key) if isinstance(uri, str) and uri.startswith("data:") else None
            if ref is None:
                continue  # nothing named it: it stays inline, as a new picture does
            try:
                data = base64.b64decode(uri.split(",", 1)[1], validate=True)
            except (IndexError, ValueError):
                continue
            try:
                same = self.image_file(i, key, ref).read_bytes() == data
            except (OSError, ValueError):
                same = False
            if same:
                layer[key] = ref
                continue
            if not data.startswith(IMAGE_MAGIC):
                continue
            suffix = ".png" if data.startswith(IMAGE_MAGIC[0]) else ".jpg"
            old = Path(ref)
            if not _inside((self.folder / old).resolve().parent, self.folder):
                old = Path(old.name)  # a picture outside the scene's folder: its copy goes beside the scene
            for n in range(1, 1000):
                name = old.with_name(f"{old.stem}-kept{'' if n == 1 else f'-{n}'}{suffix}")
                file = (self.folder / name).resolve()
                if not file.exists() and file not in taken:
                    break
            taken.add(file)
            planned.append((i, key, data, name.as_posix(), ref))
        return planned

    def write(self, body: bytes, if_match: str | None = None,
              kept: list[tuple[int, str]] | None = None) -> tuple[str, list[str]]:
        """Writes the editor's scene back, restoring the original image paths; returns the
        file's new version and a sentence for each kept copy of a picture written beside it.

        The scene is validated first (as ``inkwarp validate`` would); the file is replaced
        atomically and keeps its permissions. With ``if_match`` (a version from
        :meth:`read` or an earlier write; ``*`` for any), a file whose version is another
        one now is left as it is: :class:`ChangedOnDisk`. ``kept`` lists the ``(layer,
        key)`` pictures the editor holds a kept copy of, whose file was changed on disk
        since: each is written beside that file under a new name (``pic-kept.png``), the
        file left as it is, and the scene names the copy; never inlined in its place.
        """
        from inkwarp.scene import validate_scene

        try:
            doc: Any = json.loads(body.decode("utf-8-sig"))
        except (UnicodeDecodeError, ValueError) as err:
            raise ValueError(f"The saved scene is not JSON text ({err}).") from None
        if not isinstance(doc, dict):
            raise ValueError("A scene is a JSON object.")
        if not self.folder.is_dir():
            # (Not "the image 'face.png' does not exist" of every picture beside it.)
            raise ValueError(f"The scene's folder {self.folder} is gone (moved, renamed or deleted), so "
                             f"{self.path.name} cannot be saved there; put the folder back, or download the scene.")
        planned = self._kept_copies(doc, kept or [])
        copies = {(i, key) for i, key, *_ in planned}
        layers = doc.get("layers", [])
        for i, layer in enumerate(layers if isinstance(layers, list) else []):
            if isinstance(layer, dict):
                for key in IMAGE_KEYS:
                    uri = layer.get(key)
                    if isinstance(uri, str) and uri in self.inlined and (i, key) not in copies:
                        # The path this key of the same-named layer was read with, else of the
                        # same place's, else the latest read's.
                        froms = self.inlined[uri][::-1]
                        named = [r for r, name, _, k in froms if (name, k) == (layer.get("name"), key)]
                        placed = [r for r, _, at, k in froms if (at, k) == (i, key)]
                        layer[key] = (named or placed or [froms[0][0]])[0]
        for i, key, ref in self._image_refs(doc):
            self.image_file(i, key, ref)
        problems = validate_scene(doc, base_dir=self.folder)
        if problems:
            lines = "; ".join(f"{p}: {m}" if p else m for p, m in problems[:5])
            more = f" (and {len(problems) - 5} more)" if len(problems) > 5 else ""
            raise ValueError(f"Not saved: the scene is not valid: {lines}{more}.")
        from inkwarp._atomic import write_text

        with self.lock:
            if if_match not in (None, "*") and self.version() != if_match:
                if not self.path.exists():
                    raise ChangedOnDisk(f"{self.path} is no longer there (deleted or moved since the "
                                        "editor read it)")
                raise ChangedOnDisk(f"{self.path} changed on disk since the editor read it (another "
                                    "tab or program saved it)")
            try:
                mode = stat.S_IMODE(self.path.stat().st_mode)
            except FileNotFoundError:
                mode = 0o666 & ~_umask()
            else:
                # A rename replaces a file whatever its permissions: one locked against writing
                # (no write bit for anyone, or none for this user) is left as it is.
                if not mode & 0o222:
                    raise PermissionError(f"{self.path} is read-only (mode {mode:o}); not saved. Make it "
                                          "writable (chmod u+w), or save a copy under another name.")
                if _read_only_fs(self.folder):
                    raise _save_error(self.path, OSError(errno.EROFS, os.strerror(errno.EROFS)))
                if not os.access(self.path, os.W_OK):
                    raise PermissionError(f"{self.path} is not writable by you (mode {mode:o}, owner "
                                          f"{self.path.stat().st_uid}); not saved. Save a copy under another name.")
            written: list[Path] = []
            notes: list[str] = []
            try:
                for i, key, data, name, ref in planned:
                    file = self.folder / name
                    with open(file, "xb") as fh:  # never over a file that is there
                        written.append(file)
                        fh.write(data)
                        fh.flush()
                        os.fsync(fh.fileno())
                    layers[i][key] = name
                    notes.append(f"layers[{i}].{key}: {ref} changed on disk since the work was kept, so the "
                                 f"kept copy of its picture was written beside it as {name} ({ref} is "
                                 "left as it is)")
                text = json.dumps(doc, indent=1) + "\n"
                write_text(self.path, text, suffix=".json", mode=mode, sync=True)
            except OSError as err:
                for file in written:
                    file.unlink(missing_ok=True)
                raise _save_error(self.path, err) from None
            # Later saves name the copy by its path, as a picture read from it.
            for i, key, data, name, _ in planned:
                mime = "image/png" if name.endswith(".png") else "image/jpeg"
                uri = f"data:{mime};base64," + base64.b64encode(data).decode("ascii")
                self.inlined.setdefault(uri, []).append((name, layers[i].get("name"), i, key))
            return self.version() or self.version_of(text), notes  # the file's, as read back


def _read_only_fs(folder: Path) -> bool:
    """Whether ``folder`` is on a file system mounted read-only (False where unknown)."""
    try:
        return bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        return False


def _save_error(path: Path, err: OSError) -> OSError:
    """A failed write of ``path`` in words: a full disk or a read-only file system said so."""
    code = err.errno or getattr(err.__context__, "errno", None)  # a folder refused names the cause there
    if code in (errno.ENOSPC, errno.EDQUOT):
        why = "the disk is full" if code == errno.ENOSPC else "your disk quota is used up"
        return OSError(f"{why}: no room to write {path}; not saved. Free some space and save again")
    if code == errno.EROFS:
        return PermissionError(f"{path} is on a read-only file system; not saved. Save a copy on a "
                               "writable disk (or mount this one writable)")
    return err


class ChangedOnDisk(Exception):
    """A save whose file another writer changed since the editor read it."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


class EditorServer(ThreadingHTTPServer):
    """A threading HTTP server with a bounded number of handler threads."""

    daemon_threads = True
    request_queue_size = 64

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.slots = threading.BoundedSemaphore(MAX_WORKERS)
        self.token = secrets.token_urlsafe(32)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self.slots.acquire(blocking=False):
            try:
                request.sendall(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n"
                                b"Connection: close\r\n\r\n")
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.slots.release()
            raise

    def handle_error(self, request: Any, client_address: Any) -> None:
        # A client that stalls or hangs up mid-request is dropped without a traceback.
        pass

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.slots.release()


def make_server(scene: Path | None, root: Path, host: str = "127.0.0.1", port: int = 0) -> EditorServer:
    """The editor's HTTP server (not yet serving); ``port=0`` picks a free port.

    Every ``/api/`` request must carry the server's token (``server.token``), as the header
    ``X-Inkwarp-Token`` or the cookie the page gets when opened with ``?token=``; every
    request must name this server in ``Host`` (and ``Origin``, when sent).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> server = make_server(None, pathlib.Path(tempfile.mkdtemp()))
    >>> server.server_address[0], server.server_address[1] > 0, len(server.token) > 30
    ('127.0.0.1', True, True)
    >>> server.server_close()
    """
    scene_file = SceneFile(scene) if scene is not None else None

    timeout_s = SOCKET_TIMEOUT_S

    class Handler(SimpleHTTPRequestHandler):
        timeout = timeout_s
        protocol_version = "HTTP/1.0"
        extensions_map = {
            **SimpleHTTPRequestHandler.extensions_map,
            ".js": "text/javascript",
            ".mjs": "text/javascript",
            ".wasm": "application/wasm",
            ".json": "application/json",
        }

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, directory=str(root), **kwargs)

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib name
            pass

        @property
        def cookie_name(self) -> str:
            return f"inkwarp-token-{self.server.server_address[1]}"

        def end_headers(self) -> None:
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.send_header("Content-Security-Policy", CSP)
            self.send_header("Referrer-Policy", "no-referrer")
            self.send_header("X-Frame-Options", "DENY")
            self.send_header("Cross-Origin-Resource-Policy", "same-origin")
            super().end_headers()

        def list_directory(self, path: Any) -> None:
            self.send_error(HTTPStatus.NOT_FOUND, "No directory listings here.")
            return None

        def _reply(self, status: int, body: bytes, ctype: str = "text/plain; charset=utf-8",
                   headers: dict[str, str] | None = None) -> None:
            self.send_response(status)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(body)))
            for k, v in (headers or {}).items():
                self.send_header(k, v)
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)

        # --- who may ask ---------------------------------------------------------------

        def _allowed_hosts(self) -> set[str]:
            port = self.server.server_address[1]
            bound = self.server.server_address[0]
            names = set(LOOPBACK_NAMES) | {bound, f"[{bound}]"}
            return {f"{n}:{port}" for n in names}

        def _refused(self) -> bool:
            """Answers 403 (and returns True) unless Host, Origin and, for the API, the
            token are this server's."""
            host = (self.headers.get("Host") or "").strip().lower()
            if host not in self._allowed_hosts():
                self._reply(HTTPStatus.FORBIDDEN, b"Forbidden: the Host header does not name this "
                            b"server (open the URL inkwarp edit printed).")
                return True
            origin = self.headers.get("Origin")
            if origin is not None and origin.strip().lower() not in {
                    f"http://{h}" for h in self._allowed_hosts()}:
                self._reply(HTTPStatus.FORBIDDEN, b"Forbidden: requests from other sites are refused.")
                return True
            api = urlsplit(self.path).path
            if api.startswith("/api/") and api != "/api/serving" and not self._has_token():
                self._reply(HTTPStatus.FORBIDDEN, b"Forbidden: no valid token (open the URL "
                            b"inkwarp edit printed, with its ?token=).")
                return True
            return False

        def _has_token(self) -> bool:
            want = self.server.token.encode()
            given = self.headers.get("X-Inkwarp-Token")
            if given is not None and hmac.compare_digest(given.strip().encode(), want):
                return True
            for part in (self.headers.get("Cookie") or "").split(";"):
                name, _, value = part.strip().partition("=")
                if name == self.cookie_name and hmac.compare_digest(value.encode(), want):
                    return True
            return False

        def _token_cookie(self) -> str | None:
            """The Set-Cookie header for a page opened with the right ``?token=``."""
            query = parse_qs(urlsplit(self.path).query)
            given = (query.get("token") or [""])[0]
            if given and hmac.compare_digest(given.encode(), self.server.token.encode()):
                return (f"{self.cookie_name}={self.server.token}; Path=/; HttpOnly; "
                        "SameSite=Strict")
            return None

        def send_response(self, code: int, message: str | None = None) -> None:
            super().send_response(code, message)
            cookie = self._token_cookie() if code == HTTPStatus.OK else None
            if cookie:
                self.send_header("Set-Cookie", cookie)

        # --- methods -------------------------------------------------------------------

        def do_HEAD(self) -> None:
            if self._refused():
                return
            super().do_HEAD()

        def do_GET(self) -> None:
            if self._refused():
                return
            if urlsplit(self.path).path == "/api/scene":
                if scene_file is None:
                    return self._reply(HTTPStatus.NOT_FOUND, b"No scene was given to inkwarp edit.")
                try:
                    body, version, files = scene_file.read()
                except (OSError, ValueError) as err:
                    # Named even so: work the browser kept from this file saves back to it.
                    said = (f"{scene_file.path}: no such file (deleted or moved since inkwarp edit "
                            "opened it); Save writes it there again, or start inkwarp edit on its new "
                            "place" if isinstance(err, FileNotFoundError) and err.filename == str(scene_file.path)
                            else str(err))
                    return self._reply(HTTPStatus.UNPROCESSABLE_ENTITY, said.encode(),
                                       headers={"X-Inkwarp-Path": quote(str(scene_file.path))})
                stamps = {ref: scene_file.pictures[ref][1] for ref in files.values()}
                return self._reply(HTTPStatus.OK, body, "application/json",
                                   {"X-Inkwarp-Name": quote(scene_file.path.name),
                                    "X-Inkwarp-Path": quote(str(scene_file.path)), "ETag": version,
                                    "X-Inkwarp-Pictures": quote(json.dumps(files)),
                                    "X-Inkwarp-Stamps": quote(json.dumps(stamps))})
            if urlsplit(self.path).path == "/api/scene/version":
                # The file's version alone (nothing read into the answer): a tab asks it every
                # few seconds to notice what another tab or program wrote.
                if scene_file is None:
                    return self._reply(HTTPStatus.NOT_FOUND, b"No scene was given to inkwarp edit.")
                version = scene_file.version(cached=True)
                named = {"X-Inkwarp-Path": quote(str(scene_file.path)),
                         "X-Inkwarp-Stamps": quote(json.dumps(scene_file.stamps()))}
                if version is None:
                    return self._reply(HTTPStatus.UNPROCESSABLE_ENTITY,
                                       f"{scene_file.path} cannot be read (deleted or moved?)".encode(), headers=named)
                return self._reply(HTTPStatus.OK, version.encode(), "text/plain", {"ETag": version, **named})
            if urlsplit(self.path).path == "/api/serving":
                # Another `inkwarp edit` asks whether this one serves its scene: a hash of the
                # path answers only that (no token needed, nothing else told).
                return self._reply(HTTPStatus.OK, serving_id(scene_file.path if scene_file else None).encode())
            if urlsplit(self.path).path.startswith("/api/"):
                return self._reply(HTTPStatus.NOT_FOUND, b"No such API.")
            return super().do_GET()

        def _body(self) -> bytes | None:
            """The request's body, or None after answering why it is refused."""
            length_text = self.headers.get("Content-Length")
            if length_text is None:
                self._reply(HTTPStatus.LENGTH_REQUIRED, b"A save needs a Content-Length.")
                return None
            try:
                length = int(length_text.strip())
            except ValueError:
                length = -1
            if length < 0:
                self._reply(HTTPStatus.BAD_REQUEST, b"Content-Length must be a whole number >= 0.")
                return None
            if length > MAX_BODY_BYTES:
                self._reply(HTTPStatus.REQUEST_ENTITY_TOO_LARGE,
                            f"A saved scene may be at most {MAX_BODY_BYTES // 2**20} MiB; "
                            "keep large pictures as files beside the scene.".encode())
                return None
            chunks, left = [], length
            while left:
                chunk = self.rfile.read(min(left, 1 << 20))
                if not chunk:
                    self._reply(HTTPStatus.BAD_REQUEST, b"The request body ended early.")
                    return None
                chunks.append(chunk)
                left -= len(chunk)
            return b"".join(chunks)

        def do_PUT(self) -> None:
            if self._refused():
                return
            if urlsplit(self.path).path != "/api/scene" or scene_file is None:
                return self._reply(HTTPStatus.NOT_FOUND, b"Nothing to save to here.")
            # A tab that opened another file (a server restarted on this port with another
            # scene, the tab still open) would write its scene over this one.
            opened = unquote(self.headers.get("X-Inkwarp-Scene") or "")
            if opened and opened != str(scene_file.path):
                return self._reply(HTTPStatus.UNPROCESSABLE_ENTITY, (
                    f"this tab opened {opened}, but inkwarp edit now serves {scene_file.path}, so "
                    f"nothing was written there; open {opened} with inkwarp edit to save it in place").encode())
            body = self._body()
            if body is None:
                return
            # The pictures the editor holds a kept copy of ("0.image,1.alpha"; see SceneFile.write).
            kept = []
            for item in (self.headers.get("X-Inkwarp-Kept-Copies") or "").split(","):
                at, _, key = item.strip().partition(".")
                if at.isdigit() and key in IMAGE_KEYS:
                    kept.append((int(at), key))
            try:
                version, notes = scene_file.write(body, self.headers.get("If-Match"), kept)
            except ChangedOnDisk as err:
                return self._reply(HTTPStatus.CONFLICT, str(err).encode(),
                                   headers={"X-Inkwarp-Path": quote(str(scene_file.path))})
            except (OSError, ValueError) as err:
                return self._reply(HTTPStatus.UNPROCESSABLE_ENTITY, str(err).encode())
            headers = {"X-Inkwarp-Path": quote(str(scene_file.path)), "ETag": version}
            if notes:
                headers["X-Inkwarp-Note"] = quote("; ".join(notes))
            return self._reply(HTTPStatus.OK, b"saved", headers=headers)

        def _not_allowed(self) -> None:
            self._reply(HTTPStatus.METHOD_NOT_ALLOWED, b"Method not allowed.")

        do_POST = do_DELETE = do_PATCH = do_OPTIONS = _not_allowed

    return EditorServer((host, port), Handler)


def editor_url(server: EditorServer, with_scene: bool) -> str:
    """The URL to open: it carries the server's token, which the page keeps as a cookie."""
    host, port = server.server_address[:2]
    if ":" in host:
        host = f"[{host}]"
    return f"http://{host}:{port}/?token={server.token}" + ("&scene=/api/scene" if with_scene else "")


def run(args: argparse.Namespace) -> int:
    root = editor_dir()
    if not (root / "index.html").is_file():
        print(f"inkwarp edit: the editor is not built (no {root / 'index.html'}); run `make editor`.",
              file=sys.stderr)
        return 1
    scene: Path | None = None
    if args.scene is not None:
        scene = Path(args.scene).resolve()
        if not scene.is_file():
            raise ValueError(f"{args.scene}: no such scene file; make one from a picture with "
                             f"inkwarp new PICTURE -o {args.scene}, or run inkwarp edit without a "
                             "scene and save from the editor.")
        SceneFile(scene).read()  # bad JSON or missing images: say so now, exit 2
    try:
        server = _serve(scene, root, args.host, args.port)
    except socket.gaierror as err:
        raise ValueError(f"--host {args.host}: no such address ({err.strerror}); use 127.0.0.1 "
                         "or localhost.") from None
    except OSError as err:
        where = f"--host {args.host}" + ("" if args.port is None else f" --port {args.port}")
        raise ValueError(f"{where}: cannot serve there "
                         f"({err.strerror or err}); leave --port out to pick a free one.") from None
    url = editor_url(server, scene is not None)
    print(f"inkwarp editor at {url}" + (f" (editing {scene})" if scene else ""), flush=True)
    port = server.server_address[1]
    if args.port is None and port != DEFAULT_PORT:
        print(f"Port {DEFAULT_PORT} is taken (another inkwarp edit, or another program), so this one "
              f"serves on port {port}. The browser keeps unsaved work per address: work kept at port "
              f"{DEFAULT_PORT} is offered there, not here; open the address above.", flush=True)
        if scene is not None and _serves(args.host, DEFAULT_PORT) == serving_id(scene):
            print(f"Warning: another inkwarp edit already serves {scene} at http://{args.host}:{DEFAULT_PORT}/ . "
                  "Edit it in one place (that one's page, or stop it and run this again): two pages saving "
                  "one file each ask before writing over the other's save.", flush=True)
    print("Press Ctrl+C to stop.", flush=True)
    if not args.no_browser:
        threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
    # Served from a thread of its own while this one waits in short steps: Ctrl+C and SIGTERM
    # then always reach the command (a rare SIGTERM left the server in its select, running).
    serving = threading.Thread(target=server.serve_forever, name="inkwarp-edit-server", daemon=True)
    serving.start()
    try:
        while serving.is_alive():
            serving.join(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        server.shutdown()
        server.server_close()
    return 0


#: The port tried first. The browser keeps unsaved work per origin (host and port), so the
#: same port from one run to the next lets the editor offer it back after a restart.
DEFAULT_PORT = 8470


def _serve(scene: Path | None, root: Path, host: str, port: int | None) -> EditorServer:
    """The server on ``port``; without one on :data:`DEFAULT_PORT`, or a free port while
    that one is in use (another editor)."""
    if port is not None:
        return make_server(scene, root, host, port)
    try:
        return make_server(scene, root, host, DEFAULT_PORT)
    except OSError as err:
        if err.errno != errno.EADDRINUSE:
            raise
        return make_server(scene, root, host, 0)


def serving_id(scene: Path | None) -> str:
    """What ``/api/serving`` answers: a hash of the served scene's path ("" for none)."""
    return hashlib.sha256(str(scene).encode("utf-8")).hexdigest()[:32] if scene is not None else ""


def _serves(host: str, port: int) -> str | None:
    """What an ``inkwarp edit`` on ``host:port`` answers at ``/api/serving`` (None: no answer)."""
    import http.client

    try:
        conn = http.client.HTTPConnection(host, port, timeout=1.0)
        try:
            conn.request("GET", "/api/serving", headers={"Host": f"{host}:{port}"})
            resp = conn.getresponse()
            return resp.read(100).decode("ascii", "replace") if resp.status == 200 else None
        finally:
            conn.close()
    except (OSError, http.client.HTTPException):
        return None


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{text} is not a port; give 1 to 65535, or 0 for a free one")
    return port


def add_parser(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "edit",
        help="open the browser editor: trace, animate and preview live",
        description="Serve the inkwarp editor on 127.0.0.1 and open it in the browser. "
        "Given SCENE, the editor opens it and Save writes it back.",
        epilog="examples:\n  inkwarp edit examples/cat/scene.json\n  inkwarp edit --no-browser --port 8765\n",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scene", nargs="?", metavar="SCENE", help="a scene file to open (optional)")
    p.add_argument("--port", type=_port, default=None,
                   help=f"port to serve on (default: {DEFAULT_PORT}, or a free one when it is in use; "
                        "0: a free one)")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default: 127.0.0.1)")
    p.add_argument("--no-browser", action="store_true", help="print the URL without opening a browser")
    p.set_defaults(func=run)
