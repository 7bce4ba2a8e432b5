"""``inkwarp edit``: the server that ships the editor and round-trips a scene file."""

from __future__ import annotations

import base64
import json
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from inkwarp.cli import main
from inkwarp.cli.edit import editor_url, make_server

PNG_1x1 = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
)


@pytest.fixture
def editor(tmp_path: Path) -> Path:
    root = tmp_path / "editor"
    root.mkdir()
    (root / "index.html").write_text("<!doctype html><title>inkwarp editor</title>")
    (root / "engine.wasm").write_bytes(b"\0asm\1\0\0\0")
    (root / "main.js").write_text("export {};")
    return root


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    (tmp_path / "art").mkdir()
    (tmp_path / "art" / "dot.png").write_bytes(PNG_1x1)
    path = tmp_path / "scene.json"
    doc = {"inkwarp": 1, "width": 1, "height": 1, "layers": [{"name": "dot", "image": "art/dot.png"}], "features": []}
    path.write_text(json.dumps(doc))
    return path


def serve(scene: Path | None, root: Path):
    server = make_server(scene, root)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    return server


def fetch(url: str, method: str = "GET", body: bytes | None = None):
    req = urllib.request.Request(url, data=body, method=method)
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, resp.headers, resp.read()
    except urllib.error.HTTPError as err:
        return err.code, err.headers, err.read()


def test_serves_the_editor_on_loopback_with_module_types(editor: Path) -> None:
    server = serve(None, editor)
    try:
        url = editor_url(server, with_scene=False)
        assert url.startswith("http://127.0.0.1:")
        status, headers, body = fetch(url)
        assert status == 200 and b"inkwarp editor" in body
        assert fetch(url + "engine.wasm")[1]["Content-Type"] == "application/wasm"
        assert fetch(url + "main.js")[1]["Content-Type"].startswith("text/javascript")
        assert fetch(url + "api/scene")[0] == 404
    finally:
        server.shutdown()
        server.server_close()


def test_scene_images_are_inlined_and_paths_restored_on_save(editor: Path, scene: Path) -> None:
    server = serve(scene, editor)
    try:
        url = editor_url(server, with_scene=True)
        assert url.endswith("?scene=/api/scene")
        api = url.split("?")[0] + "api/scene"
        status, headers, body = fetch(api)
        assert status == 200
        assert headers["X-Inkwarp-Name"] == "scene.json"
        doc = json.loads(body)
        uri = doc["layers"][0]["image"]
        assert uri == "data:image/png;base64," + base64.b64encode(PNG_1x1).decode()
        # The editor saves: the known image goes back to its path, a new matte stays inline.
        doc["features"].append({"id": "p", "kind": "point", "rest": [[0, 0]]})
        doc["layers"][0]["continuity"] = "data:image/png;base64,AAAA"
        status, _, _ = fetch(api, "PUT", json.dumps(doc).encode())
        assert status == 200
        saved = json.loads(scene.read_text())
        assert saved["layers"][0]["image"] == "art/dot.png"
        assert saved["layers"][0]["continuity"] == "data:image/png;base64,AAAA"
        assert saved["features"] == [{"id": "p", "kind": "point", "rest": [[0, 0]]}]
        assert [p.name for p in scene.parent.iterdir() if p.name.startswith(".scene")] == []
        # A body that is not a scene is refused and leaves the file alone.
        status, _, body = fetch(api, "PUT", b"[1, 2]")
        assert status == 422 and b"JSON object" in body
        assert json.loads(scene.read_text()) == saved
    finally:
        server.shutdown()
        server.server_close()


def test_missing_image_is_reported_with_its_json_path(editor: Path, scene: Path) -> None:
    (scene.parent / "art" / "dot.png").unlink()
    server = serve(scene, editor)
    try:
        status, _, body = fetch(editor_url(server, False) + "api/scene")
        assert status == 422
        assert b"layers[0].image" in body and b"art/dot.png" in body
    finally:
        server.shutdown()
        server.server_close()


def test_cli_refuses_a_missing_scene_with_exit_2(editor: Path, tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    assert main(["edit", "--no-browser", str(tmp_path / "nope.json")]) == 2
    err = capsys.readouterr().err
    assert "nope.json" in err and "no such scene" in err


def test_cli_says_when_the_editor_is_not_built(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(tmp_path / "missing"))
    assert main(["edit", "--no-browser"]) == 1
    assert "make editor" in capsys.readouterr().err


def test_edit_is_listed_in_help(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["edit", "--help"])
    out = capsys.readouterr().out
    assert "inkwarp edit examples/cat/scene.json" in out
