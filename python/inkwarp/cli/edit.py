"""``inkwarp edit [SCENE]``: serve the browser editor on this machine and open it.

The editor is a static web application shipped inside the package (``inkwarp/editor/``,
built from ``web/`` by ``make editor``). This command serves it on 127.0.0.1 at a free
port. Given a scene, it also serves ``/api/scene``: the scene with its images inlined as
``data:`` URIs (GET), and a way to save it back (PUT) — images that came from files keep
their relative paths when the scene is written back, new ones stay inline.
"""

from __future__ import annotations

import argparse
import base64
import json
import mimetypes
import os
import sys
import tempfile
import threading
import webbrowser
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

IMAGE_KEYS = ("image", "alpha", "continuity")
MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}


def editor_dir() -> Path:
    """Where the built editor is (``INKWARP_EDITOR_DIR`` overrides, for development)."""
    override = os.environ.get("INKWARP_EDITOR_DIR")
    if override:
        return Path(override)
    return Path(__file__).resolve().parent.parent / "editor"


class SceneFile:
    """A scene on disk as the editor sees it: images inlined, and written back with paths.

    Parameters
    ----------
    path : pathlib.Path
        The scene file.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.inlined: dict[str, str] = {}

    def read(self) -> bytes:
        """The scene as JSON with every relative image path replaced by a data: URI."""
        try:
            doc = json.loads(self.path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as err:
            raise ValueError(
                f"{self.path}: not valid JSON (line {err.lineno}, column {err.colno}: {err.msg})."
            ) from None
        for i, layer in enumerate(doc.get("layers", []) if isinstance(doc, dict) else []):
            if not isinstance(layer, dict):
                continue
            for key in IMAGE_KEYS:
                ref = layer.get(key)
                if not isinstance(ref, str) or ref.startswith("data:"):
                    continue
                file = (self.path.parent / ref).resolve()
                if not file.is_file():
                    raise ValueError(f"{self.path}: layers[{i}].{key}: the image {ref!r} does not exist.")
                mime = MIME.get(file.suffix.lower()) or mimetypes.guess_type(file.name)[0] or "image/png"
                uri = f"data:{mime};base64," + base64.b64encode(file.read_bytes()).decode("ascii")
                self.inlined[uri] = ref
                layer[key] = uri
        return json.dumps(doc).encode("utf-8")

    def write(self, body: bytes) -> None:
        """Writes the editor's scene back (atomically), restoring the original image paths."""
        doc: Any = json.loads(body)
        if not isinstance(doc, dict):
            raise ValueError("A scene is a JSON object.")
        for layer in doc.get("layers", []):
            if isinstance(layer, dict):
                for key in IMAGE_KEYS:
                    ref = layer.get(key)
                    if isinstance(ref, str) and ref in self.inlined:
                        layer[key] = self.inlined[ref]
        text = json.dumps(doc, indent=1) + "\n"
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def make_server(scene: Path | None, root: Path, host: str = "127.0.0.1", port: int = 0) -> ThreadingHTTPServer:
    """The editor's HTTP server (not yet serving); ``port=0`` picks a free port.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> server = make_server(None, pathlib.Path(tempfile.mkdtemp()))
    >>> server.server_address[0], server.server_address[1] > 0
    ('127.0.0.1', True)
    >>> server.server_close()
    """
    scene_file = SceneFile(scene) if scene is not None else None

    class Handler(SimpleHTTPRequestHandler):
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

        def end_headers(self) -> None:
            self.send_header("Cache-Control", "no-store")
            super().end_headers()

        def _reply(self, status: int, body: bytes, ctype: str = "text/plain; charset=utf-8",
                   headers: dict[str, str] | None = None) -> None:
            self.send_response(status)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(body)))
            for k, v in (headers or {}).items():
                self.send_header(k, v)
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self) -> None:
            if self.path.split("?")[0] == "/api/scene":
                if scene_file is None:
                    return self._reply(HTTPStatus.NOT_FOUND, b"No scene was given to inkwarp edit.")
                try:
                    body = scene_file.read()
                except (OSError, ValueError) as err:
                    return self._reply(HTTPStatus.UNPROCESSABLE_ENTITY, str(err).encode())
                return self._reply(HTTPStatus.OK, body, "application/json",
                                   {"X-Inkwarp-Name": scene_file.path.name, "X-Inkwarp-Path": str(scene_file.path)})
            return super().do_GET()

        def do_PUT(self) -> None:
            if self.path.split("?")[0] != "/api/scene" or scene_file is None:
                return self._reply(HTTPStatus.NOT_FOUND, b"Nothing to save to here.")
            length = int(self.headers.get("Content-Length", "0"))
            try:
                scene_file.write(self.rfile.read(length))
            except (OSError, ValueError) as err:
                return self._reply(HTTPStatus.UNPROCESSABLE_ENTITY, str(err).encode())
            return self._reply(HTTPStatus.OK, b"saved", headers={"X-Inkwarp-Path": str(scene_file.path)})

    return ThreadingHTTPServer((host, port), Handler)


def editor_url(server: ThreadingHTTPServer, with_scene: bool) -> str:
    host, port = server.server_address[:2]
    return f"http://{host}:{port}/" + ("?scene=/api/scene" if with_scene else "")


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
            raise ValueError(f"{args.scene}: no such scene file.")
        SceneFile(scene).read()  # bad JSON or missing images: say so now, exit 2
    server = make_server(scene, root, args.host, args.port)
    url = editor_url(server, scene is not None)
    print(f"inkwarp editor at {url}" + (f" (editing {scene})" if scene else ""), flush=True)
    print("Press Ctrl+C to stop.", flush=True)
    if not args.no_browser:
        threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    return 0


def add_parser(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "edit",
        help="open the browser editor: trace, animate and preview live",
        description="Serve the inkwarp editor on 127.0.0.1 and open it in the browser. "
        "Given SCENE, the editor opens it and Save writes it back.",
        epilog="examples:\n  inkwarp edit examples/cat/scene.json",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scene", nargs="?", metavar="SCENE", help="a scene file to open (optional)")
    p.add_argument("--port", type=int, default=0, help="port to serve on (default: a free one)")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default: 127.0.0.1)")
    p.add_argument("--no-browser", action="store_true", help="print the URL without opening a browser")
    p.set_defaults(func=run)
