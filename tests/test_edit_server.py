"""``inkwarp edit``: the server that ships the editor and round-trips a scene file."""

from __future__ import annotations

import base64
import http.client
import errno
import json
import re
import os
import socket
import stat
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from inkwarp import image_data_uri
from inkwarp.cli import main
from inkwarp.cli.edit import editor_url, make_server

PNG_1x1 = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
)

DOT_URI = "data:image/png;base64," + base64.b64encode(PNG_1x1).decode()
WHITE_URI = image_data_uri(np.full((1, 1, 4), 255, np.uint8))


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


TOKEN = [""]


def serve(scene: Path | None, root: Path):
    server = make_server(scene, root)
    TOKEN[0] = server.token
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    return server


def api_url(server) -> str:
    return "http://127.0.0.1:%d/api/scene" % server.server_address[1]


def fetch(url: str, method: str = "GET", body: bytes | None = None, headers: dict | None = None,
          token: object = True):
    """One request; the server's token goes in ``X-Inkwarp-Token`` unless ``token`` is
    False (or is the string to send instead)."""
    headers = dict(headers or {})
    if token is not False and "token=" not in url:
        headers.setdefault("X-Inkwarp-Token", token if isinstance(token, str) else TOKEN[0])
    req = urllib.request.Request(url, data=body, method=method, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, resp.headers, resp.read()
    except urllib.error.HTTPError as err:
        return err.code, err.headers, err.read()


def test_serves_the_editor_on_loopback_with_module_types(editor: Path) -> None:
    server = serve(None, editor)
    try:
        url = editor_url(server, with_scene=False)
        assert url.startswith("http://127.0.0.1:") and f"?token={server.token}" in url
        status, headers, body = fetch(url)
        assert status == 200 and b"inkwarp editor" in body
        base = url.split("?")[0]
        assert fetch(base + "engine.wasm")[1]["Content-Type"] == "application/wasm"
        assert fetch(base + "main.js")[1]["Content-Type"].startswith("text/javascript")
        assert fetch(base + "api/scene")[0] == 404
    finally:
        server.shutdown()
        server.server_close()


def test_scene_images_are_inlined_and_paths_restored_on_save(editor: Path, scene: Path) -> None:
    server = serve(scene, editor)
    try:
        url = editor_url(server, with_scene=True)
        assert url.endswith("&scene=/api/scene")
        api = url.split("?")[0] + "api/scene"
        status, headers, body = fetch(api)
        assert status == 200
        assert headers["X-Inkwarp-Name"] == "scene.json"  # percent-encoded where it must be
        doc = json.loads(body)
        uri = doc["layers"][0]["image"]
        assert uri == "data:image/png;base64," + base64.b64encode(PNG_1x1).decode()
        # The editor saves: the known image goes back to its path, a new matte stays inline.
        doc["features"].append({"id": "p", "kind": "point", "rest": [[0, 0]]})
        doc["layers"][0]["continuity"] = WHITE_URI
        status, _, _ = fetch(api, "PUT", json.dumps(doc).encode())
        assert status == 200
        saved = json.loads(scene.read_text())
        assert saved["layers"][0]["image"] == "art/dot.png"
        assert saved["layers"][0]["continuity"] == WHITE_URI
        assert saved["features"] == [{"id": "p", "kind": "point", "rest": [[0, 0]]}]
        assert [p.name for p in scene.parent.iterdir() if p.name.startswith(".scene")] == []
        # A body that is not a scene is refused and leaves the file alone.
        status, _, body = fetch(api, "PUT", b"[1, 2]")
        assert status == 422 and b"JSON object" in body
        assert json.loads(scene.read_text()) == saved
    finally:
        server.shutdown()
        server.server_close()


def test_each_inlined_picture_is_named_by_its_path_and_saved_back_to_it(editor: Path, scene: Path) -> None:
    # The editor's messages name a picture by its file: the server says which path (as the
    # scene file writes it) each data: URI stands for; a save writes those paths back.
    (scene.parent / "art" / "猫.png").write_bytes(PNG_1x1)
    doc = {"inkwarp": 1, "width": 1, "height": 1, "features": [], "layers": [
        {"name": "dot", "image": "art/dot.png", "continuity": "./art/猫.png"},
        {"name": "inline", "image": WHITE_URI, "alpha": "art/dot.png"}]}
    scene.write_text(json.dumps(doc))
    server = serve(scene, editor)
    try:
        status, headers, body = fetch(api_url(server))
        assert status == 200
        files = json.loads(urllib.parse.unquote(headers["X-Inkwarp-Pictures"]))
        assert files == {"0.image": "art/dot.png", "0.continuity": "./art/猫.png", "1.alpha": "art/dot.png"}
        assert all(json.loads(body)["layers"][int(at[0])][at[2:]].startswith("data:") for at in files)
        status, _, _ = fetch(api_url(server), "PUT", body)
        assert status == 200 and json.loads(scene.read_text()) == doc
    finally:
        server.shutdown()
        server.server_close()


def test_missing_image_is_reported_with_its_json_path(editor: Path, scene: Path) -> None:
    (scene.parent / "art" / "dot.png").unlink()
    server = serve(scene, editor)
    try:
        status, _, body = fetch(api_url(server))
        assert status == 422
        assert b"layers[0].image" in body and b"art/dot.png" in body
    finally:
        server.shutdown()
        server.server_close()


def test_a_damaged_picture_is_named_by_its_file_not_its_data_uri(editor: Path, scene: Path, monkeypatch, capsys) -> None:
    # Cut short while the server runs: the page is told the file; at start, exit 2.
    picture = scene.parent / "art" / "dot.png"
    server = serve(scene, editor)
    try:
        data = picture.read_bytes()
        picture.write_bytes(data[: len(data) // 2])
        status, _, body = fetch(api_url(server))
        assert status == 422, body
        assert b"layers[0].image: cannot use 'art/dot.png': the picture could not be decoded" in body, body
        assert b"data:" not in body
    finally:
        server.shutdown()
        server.server_close()
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    assert main(["edit", "--no-browser", str(scene)]) == 2
    assert "cannot use 'art/dot.png': the picture could not be decoded" in capsys.readouterr().err


def test_a_scene_with_a_key_given_twice_is_not_opened(editor: Path, scene: Path) -> None:
    # Opened, its first save would have dropped one of the two values without a word.
    text = scene.read_text()
    scene.write_text(text.replace('"width": ', '"width": 3, "width": ', 1))
    assert scene.read_text() != text
    server = serve(scene, editor)
    try:
        status, _, body = fetch(api_url(server))
        assert status == 422 and b"width: given more than once" in body, body
    finally:
        server.shutdown()
        server.server_close()


def test_cli_refuses_a_missing_scene_with_exit_2(editor: Path, tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    assert main(["edit", "--no-browser", str(tmp_path / "nope.json")]) == 2
    err = capsys.readouterr().err
    assert "nope.json" in err and "no such scene" in err and "inkwarp new PICTURE -o" in err


def test_cli_names_a_picture_given_as_the_scene(editor: Path, tmp_path: Path, monkeypatch, capsys) -> None:
    from PIL import Image

    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    Image.new("RGB", (8, 6)).save(tmp_path / "pic.png")
    assert main(["edit", "--no-browser", str(tmp_path / "pic.png")]) == 2
    assert "pic.png: a PNG picture, not a scene; make a scene of it with inkwarp new" in capsys.readouterr().err


def test_cli_says_when_the_editor_is_not_built(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(tmp_path / "missing"))
    assert main(["edit", "--no-browser"]) == 1
    assert "make editor" in capsys.readouterr().err


def test_edit_is_listed_in_help(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["edit", "--help"])
    out = capsys.readouterr().out
    assert "inkwarp edit examples/cat/scene.json" in out


def test_a_save_over_a_file_changed_since_it_was_read_is_refused(editor: Path, scene: Path) -> None:
    # Two tabs on one scene, or the file edited by another program: each save carries the
    # version it read (If-Match); one that another writer overtook is refused (409) and
    # the file keeps what that writer wrote, until the editor says to overwrite (*).
    server = serve(scene, editor)
    try:
        api = api_url(server)
        status, headers, body = fetch(api)
        read_version = headers["ETag"]
        assert status == 200 and read_version.startswith('"')
        tab_a, tab_b = json.loads(body), json.loads(body)
        tab_a["features"] = [{"id": "a", "kind": "point", "rest": [[0, 0]]}]
        status, headers, _ = fetch(api, "PUT", json.dumps(tab_a).encode(), {"If-Match": read_version})
        assert status == 200 and headers["ETag"] not in (None, read_version)
        a_version = headers["ETag"]
        assert fetch(api)[1]["ETag"] == a_version  # the version a save answers is the file's
        tab_b["features"] = [{"id": "b", "kind": "point", "rest": [[0, 0]]}]
        status, headers, body = fetch(api, "PUT", json.dumps(tab_b).encode(), {"If-Match": read_version})
        assert status == 409 and b"changed on disk since the editor read it" in body
        assert str(scene).encode() in body
        assert json.loads(scene.read_text())["features"][0]["id"] == "a"
        # Edited on disk by hand: the same.
        scene.write_text(scene.read_text().replace('"a"', '"nose"'))
        status, _, _ = fetch(api, "PUT", json.dumps(tab_a).encode(), {"If-Match": a_version})
        assert status == 409 and json.loads(scene.read_text())["features"][0]["id"] == "nose"
        # Told to overwrite, or with no version at all (a script), the save goes through.
        assert fetch(api, "PUT", json.dumps(tab_b).encode(), {"If-Match": "*"})[0] == 200
        assert json.loads(scene.read_text())["features"][0]["id"] == "b"
        assert fetch(api, "PUT", json.dumps(tab_a).encode())[0] == 200
        assert json.loads(scene.read_text())["features"][0]["id"] == "a"
    finally:
        server.shutdown()
        server.server_close()


def test_the_files_version_alone_follows_every_writer(editor: Path, scene: Path) -> None:
    # What a tab asks every few seconds to notice another writer: the version the scene's
    # GET and PUT answer, nothing read into the answer, and a file gone said as such.
    server = serve(scene, editor)
    try:
        api = api_url(server)
        read_version = fetch(api)[1]["ETag"]
        status, headers, body = fetch(api + "/version")
        assert status == 200 and body.decode() == headers["ETag"] == read_version
        assert urllib.parse.unquote(headers["X-Inkwarp-Path"]) == str(scene)  # a tab asks only of its own file
        assert headers["Cache-Control"] == "no-store"
        assert fetch(api + "/version", token=False)[0] == 403
        doc = json.loads(fetch(api)[2])
        doc["features"] = [{"id": "a", "kind": "point", "rest": [[0, 0]]}]
        saved = fetch(api, "PUT", json.dumps(doc).encode(), {"If-Match": read_version})[1]["ETag"]
        assert fetch(api + "/version")[1]["ETag"] == saved != read_version
        scene.write_text(scene.read_text().replace('"a"', '"nose"'))
        assert fetch(api + "/version")[1]["ETag"] not in (saved, read_version)
        # Each picture the scene names is stamped: the same until another program writes it.
        opened = json.loads(urllib.parse.unquote(fetch(api)[1]["X-Inkwarp-Stamps"]))
        stamps = lambda: json.loads(urllib.parse.unquote(fetch(api + "/version")[1]["X-Inkwarp-Stamps"]))  # noqa: E731
        assert list(opened) == ["art/dot.png"] and opened["art/dot.png"] and stamps() == opened
        picture = scene.parent / "art" / "dot.png"
        picture.write_bytes(PNG_1x1 + b"\0")
        assert stamps()["art/dot.png"] not in ("", opened["art/dot.png"])
        picture.unlink()
        assert stamps() == {"art/dot.png": ""}
        scene.unlink()
        status, _, body = fetch(api + "/version")
        assert status == 422 and str(scene).encode() in body and b"cannot be read" in body
    finally:
        server.shutdown()
        server.server_close()
    server = serve(None, editor)
    try:
        assert fetch(api_url(server) + "/version")[0] == 404
    finally:
        server.shutdown()
        server.server_close()


def test_a_tab_that_opened_another_file_never_writes_this_one(editor: Path, scene: Path, tmp_path: Path) -> None:
    # inkwarp edit stopped and started again on the same port with another scene, the old
    # tab still open: its save (with "overwrite" answered to the version conflict) wrote
    # its scene into the other file.
    from urllib.parse import quote

    server = serve(scene, editor)
    try:
        api = api_url(server)
        status, headers, body = fetch(api)
        assert status == 200 and headers["X-Inkwarp-Path"] == quote(str(scene))
        mine = json.loads(body)
        mine["features"] = [{"id": "mine", "kind": "point", "rest": [[0, 0]]}]
        before = scene.read_text()
        other = str(tmp_path / "other" / "scene.json")
        for version in (headers["ETag"], "*"):
            status, _, said = fetch(api, "PUT", json.dumps(mine).encode(),
                                    {"If-Match": version, "X-Inkwarp-Scene": quote(other)})
            assert status == 422 and f"this tab opened {other}, but inkwarp edit now serves {scene}".encode() in said
            assert scene.read_text() == before
        status, _, _ = fetch(api, "PUT", json.dumps(mine).encode(), {"If-Match": "*", "X-Inkwarp-Scene": quote(str(scene))})
        assert status == 200 and json.loads(scene.read_text())["features"][0]["id"] == "mine"
        # A file deleted since it was read is not called "changed".
        version = fetch(api)[1]["ETag"]
        scene.unlink()
        status, _, said = fetch(api, "PUT", json.dumps(mine).encode(), {"If-Match": version})
        assert status == 409 and b"is no longer there (deleted or moved" in said
    finally:
        server.shutdown()
        server.server_close()


def test_a_scene_in_a_folder_named_in_any_script_opens_and_saves(editor: Path, tmp_path: Path) -> None:
    # Its path went into a response header as it was; one outside Latin-1 made the server
    # drop the connection, so the editor could not open the scene at all.
    from urllib.parse import quote, unquote

    folder = tmp_path / "日本語 scènes"
    folder.mkdir()
    path = folder / "猫.json"
    path.write_text(json.dumps({"inkwarp": 1, "width": 2, "height": 2, "layers": [{"name": "a"}]}))
    server = serve(path, editor)
    try:
        status, headers, body = fetch(api_url(server))
        assert status == 200 and unquote(headers["X-Inkwarp-Path"]) == str(path)
        assert unquote(headers["X-Inkwarp-Name"]) == "猫.json"
        status, headers, _ = fetch(api_url(server), "PUT", body, {"If-Match": headers["ETag"],
                                                                  "X-Inkwarp-Scene": quote(str(path))})
        assert status == 200 and unquote(headers["X-Inkwarp-Path"]) == str(path)
    finally:
        server.shutdown()
        server.server_close()


# --- Who may ask, and what may be read --------------------------------------------------


def raw(server, request: bytes, timeout: float = 10) -> bytes:
    """Sends ``request`` as is and returns everything the server answers."""
    with socket.create_connection(server.server_address[:2], timeout=timeout) as sock:
        sock.sendall(request)
        chunks = []
        while chunk := sock.recv(65536):
            chunks.append(chunk)
    return b"".join(chunks)


@pytest.fixture
def served(editor: Path, scene: Path):
    server = serve(scene, editor)
    yield server
    server.shutdown()
    server.server_close()


def test_the_api_needs_the_token(served, scene: Path) -> None:
    api = api_url(served)
    assert fetch(api, token=False)[0] == 403
    assert fetch(api, token="x" * 43)[0] == 403
    assert fetch(api, "PUT", b"{}", token=False)[0] == 403
    assert fetch(api)[0] == 200
    # The page opened with ?token= gets an HttpOnly, SameSite=Strict cookie that then works.
    status, headers, _ = fetch(editor_url(served, True))
    cookie = headers["Set-Cookie"]
    assert status == 200 and "HttpOnly" in cookie and "SameSite=Strict" in cookie
    name_value = cookie.split(";")[0]
    assert name_value == f"inkwarp-token-{served.server_address[1]}={served.token}"
    assert fetch(api, headers={"Cookie": name_value}, token=False)[0] == 200
    assert fetch(api, headers={"Cookie": "inkwarp-token-1=" + served.token}, token=False)[0] == 403
    # A wrong token sets no cookie.
    assert "Set-Cookie" not in fetch(api.replace("api/scene", "?token=nope"))[1]


@pytest.mark.parametrize("host", ["evil.example", "evil.example:%d", "127.0.0.1:1", "localhost"])
def test_other_hosts_are_refused(served, host: str) -> None:
    port = served.server_address[1]
    host = host % port if "%d" in host else host
    answer = raw(served, f"GET /api/scene HTTP/1.1\r\nHost: {host}\r\nX-Inkwarp-Token: "
                         f"{served.token}\r\nConnection: close\r\n\r\n".encode())
    assert answer.startswith(b"HTTP/1.0 403"), answer[:80]
    for good in (f"127.0.0.1:{port}", f"localhost:{port}"):
        answer = raw(served, f"GET /api/scene HTTP/1.1\r\nHost: {good}\r\nX-Inkwarp-Token: "
                             f"{served.token}\r\n\r\n".encode())
        assert answer.startswith(b"HTTP/1.0 200")


def test_other_origins_are_refused(served) -> None:
    api = api_url(served)
    port = served.server_address[1]
    for origin in ("http://evil.example", "null", f"http://127.0.0.1:{port + 1}", "https://127.0.0.1"):
        assert fetch(api, headers={"Origin": origin})[0] == 403, origin
        assert fetch(api, "PUT", b"{}", headers={"Origin": origin})[0] == 403, origin
    assert fetch(api, headers={"Origin": f"http://127.0.0.1:{port}"})[0] == 200
    assert fetch(api, headers={"Origin": f"http://localhost:{port}"})[0] == 200


@pytest.mark.parametrize("target", ["/etc/passwd", "/proc/self/environ", "../outside.png",
                                    "art/../../outside.png", "art/link.png", "art/fake.png",
                                    "art/fifo.png", "art"])
def test_images_outside_the_scene_folder_are_never_read(served, scene: Path, target: str) -> None:
    outside = scene.parent.parent / "outside.png"
    outside.write_bytes(PNG_1x1)
    (scene.parent / "art" / "link.png").unlink(missing_ok=True)
    (scene.parent / "art" / "link.png").symlink_to("/etc/passwd")
    (scene.parent / "art" / "fake.png").write_text("SECRET=1")
    if not (scene.parent / "art" / "fifo.png").exists():
        os.mkfifo(scene.parent / "art" / "fifo.png")
    before = scene.read_bytes()
    mode = stat.S_IMODE(scene.stat().st_mode)
    api = api_url(served)
    doc = json.loads(fetch(api)[2])
    doc["layers"][0]["image"] = target
    status, _, body = fetch(api, "PUT", json.dumps(doc).encode())
    assert status == 422, body
    assert scene.read_bytes() == before and stat.S_IMODE(scene.stat().st_mode) == mode
    # Even when the file itself is edited to name it, the server inlines nothing of it.
    scene.write_text(json.dumps({**json.loads(before), "layers": [{"name": "x", "image": target}]}))
    status, _, body = fetch(api)
    assert status == 422 and b"root:" not in body and b"SECRET" not in body and b"PATH=" not in body
    assert b"layers[0].image" in body


def test_images_the_scene_file_named_at_start_stay_readable(editor: Path, tmp_path: Path) -> None:
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "dot.png").write_bytes(PNG_1x1)
    (tmp_path / "scene").mkdir()
    path = tmp_path / "scene" / "s.json"
    path.write_text(json.dumps({"inkwarp": 1, "width": 1, "height": 1,
                                "layers": [{"name": "d", "image": "../shared/dot.png"}]}))
    server = serve(path, editor)
    try:
        status, _, body = fetch(api_url(server))
        assert status == 200 and json.loads(body)["layers"][0]["image"] == DOT_URI
        assert fetch(api_url(server), "PUT", body)[0] == 200
        assert json.loads(path.read_text())["layers"][0]["image"] == "../shared/dot.png"
    finally:
        server.shutdown()
        server.server_close()


def test_saves_are_validated_size_limited_and_keep_the_mode(served, scene: Path) -> None:
    api = api_url(served)
    os.chmod(scene, 0o644)
    doc = json.loads(fetch(api)[2])
    bad = {**doc, "fps": -1}
    status, _, body = fetch(api, "PUT", json.dumps(bad).encode())
    assert status == 422 and b"fps" in body
    assert fetch(api, "PUT", b"\xff\xfe not json")[0] == 422
    status, _, body = fetch(api, "PUT", json.dumps(doc).encode())
    assert status == 200
    assert stat.S_IMODE(scene.stat().st_mode) == 0o644
    os.chmod(scene, 0o664)
    assert fetch(api, "PUT", json.dumps(doc).encode())[0] == 200
    assert stat.S_IMODE(scene.stat().st_mode) == 0o664
    # A UTF-8 byte-order mark, as some editors write, is fine.
    scene.write_bytes(b"\xef\xbb\xbf" + scene.read_bytes())
    assert fetch(api)[0] == 200
    port = served.server_address[1]
    head = f"PUT /api/scene HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Inkwarp-Token: {served.token}\r\n"
    assert raw(served, (head + "Content-Length: -1\r\n\r\n").encode()).startswith(b"HTTP/1.0 400")
    assert raw(served, (head + "Content-Length: abc\r\n\r\n").encode()).startswith(b"HTTP/1.0 400")
    assert raw(served, (head + "\r\n").encode()).startswith(b"HTTP/1.0 411")
    huge = raw(served, (head + f"Content-Length: {10**15}\r\n\r\n").encode())
    assert huge.startswith(b"HTTP/1.0 413") and b"MiB" in huge
    assert [p.name for p in scene.parent.iterdir() if p.name.startswith(".")] == []


def test_a_save_into_a_folder_that_is_gone_says_so(served, scene: Path) -> None:
    # Moved or deleted while the editor was open: the message named a missing picture.
    api = api_url(served)
    doc = json.loads(fetch(api)[2])
    moved = scene.parent.with_name(scene.parent.name + "-moved")
    scene.parent.rename(moved)
    try:
        status, _, body = fetch(api, "PUT", json.dumps({**doc, "fps": 12}).encode())
        assert status == 422 and body.decode().startswith(f"The scene's folder {scene.parent} is gone (moved, renamed or "
                                                          "deleted), so scene.json cannot be saved there"), body
        assert b"does not exist" not in body and not scene.parent.exists()
    finally:
        moved.rename(scene.parent)
    assert fetch(api, "PUT", json.dumps({**doc, "fps": 12}).encode())[0] == 200


def test_a_scene_file_deleted_while_served_is_said_in_words(served, scene: Path) -> None:
    # A reload after the file went showed Python's "[Errno 2] No such file or directory".
    api = api_url(served)
    doc = json.loads(fetch(api)[2])
    scene.unlink()
    status, headers, body = fetch(api)
    assert status == 422 and body.decode().startswith(f"{scene}: no such file (deleted or moved since "
                                                      "inkwarp edit opened it); Save writes it there again"), body
    assert b"Errno" not in body
    assert fetch(api, "PUT", json.dumps(doc).encode())[0] == 200 and scene.exists()


def test_a_read_only_scene_file_is_not_replaced(served, scene: Path) -> None:
    # A rename replaces a file whatever its mode: a file locked against writing (even for a
    # user the system lets write anything) is left alone, with a message saying why.
    api = api_url(served)
    doc = json.loads(fetch(api)[2])
    before = scene.read_bytes()
    os.chmod(scene, 0o444)
    try:
        status, _, body = fetch(api, "PUT", json.dumps({**doc, "fps": 12}).encode())
        assert status == 422 and b"read-only (mode 444); not saved" in body and b"chmod u+w" in body
        assert scene.read_bytes() == before and stat.S_IMODE(scene.stat().st_mode) == 0o444
    finally:
        os.chmod(scene, 0o644)
    assert fetch(api, "PUT", json.dumps({**doc, "fps": 12}).encode())[0] == 200


def test_two_pictures_with_the_same_bytes_keep_their_own_paths(editor: Path, scene: Path) -> None:
    # Layers a and b name two files with the same bytes, so the same data: URI: an
    # unchanged save wrote the last file's path into both layers.
    (scene.parent / "art" / "copy.png").write_bytes(PNG_1x1)
    doc = json.loads(scene.read_text())
    doc["layers"] = [{"name": "a", "image": "art/dot.png"}, {"name": "b", "image": "art/copy.png"}]
    scene.write_text(json.dumps(doc))
    server = serve(scene, editor)
    try:
        api = api_url(server)
        edited = json.loads(fetch(api)[2])
        assert edited["layers"][0]["image"] == edited["layers"][1]["image"]
        assert fetch(api, "PUT", json.dumps(edited).encode())[0] == 200
        assert [layer["image"] for layer in json.loads(scene.read_text())["layers"]] == ["art/dot.png", "art/copy.png"]
        # One layer's picture and continuity matte, copies of each other, keep theirs too.
        doc["layers"] = [{"name": "a", "image": "art/dot.png", "continuity": "art/copy.png"}]
        scene.write_text(json.dumps(doc))
        one = json.loads(fetch(api)[2])
        assert fetch(api, "PUT", json.dumps(one).encode())[0] == 200
        saved = json.loads(scene.read_text())["layers"][0]
        assert (saved["image"], saved["continuity"]) == ("art/dot.png", "art/copy.png")
        doc["layers"] = [{"name": "a", "image": "art/dot.png"}, {"name": "b", "image": "art/copy.png"}]
        scene.write_text(json.dumps(doc))
        edited = json.loads(fetch(api)[2])
        # Reordered in the editor, each layer keeps its own path by its name.
        edited["layers"].reverse()
        assert fetch(api, "PUT", json.dumps(edited).encode())[0] == 200
        assert [layer["image"] for layer in json.loads(scene.read_text())["layers"]] == ["art/copy.png", "art/dot.png"]
    finally:
        server.shutdown()
        server.server_close()


def test_security_headers_and_no_listings(served, editor: Path) -> None:
    (editor / "assets").mkdir()
    (editor / "assets" / "a.js").write_text("1")
    base = api_url(served).replace("api/scene", "")
    status, headers, _ = fetch(base)
    assert headers["X-Content-Type-Options"] == "nosniff"
    csp = headers["Content-Security-Policy"]
    assert "'wasm-unsafe-eval'" in csp and "worker-src 'self' blob:" in csp
    assert "frame-ancestors 'none'" in csp and headers["Referrer-Policy"] == "no-referrer"
    assert fetch(base + "assets/")[0] == 404
    assert fetch(base + "assets")[0] in (301, 404)
    assert fetch(base + "../../../../etc/passwd")[0] == 404
    assert fetch(base + "api/scene", "POST", b"{}")[0] == 405


def test_stalled_clients_time_out_and_do_not_starve_others(served, monkeypatch) -> None:
    import inkwarp.cli.edit as edit

    port = served.server_address[1]
    stalled = [socket.create_connection(("127.0.0.1", port)) for _ in range(40)]
    try:
        for s in stalled[:5]:
            s.sendall(b"PUT /api/scene HTTP/1.1\r\n")
        time.sleep(0.3)
        # The pool is bounded: past MAX_WORKERS the server answers 503 at once ...
        answers = []
        for s in stalled[edit.MAX_WORKERS:]:
            s.settimeout(5)
            answers.append(s.recv(100))
        assert all(a.startswith(b"HTTP/1.1 503") for a in answers), answers[:3]
        assert threading.active_count() < 80
    finally:
        for s in stalled:
            s.close()
    # ... and once they hang up, it serves again.
    deadline = time.monotonic() + 10
    while fetch(api_url(served))[0] != 200:
        assert time.monotonic() < deadline
        time.sleep(0.1)


def test_a_silent_client_is_dropped_after_the_socket_timeout(editor: Path, scene: Path,
                                                              monkeypatch) -> None:
    import inkwarp.cli.edit as edit

    monkeypatch.setattr(edit, "SOCKET_TIMEOUT_S", 0.5)
    server = serve(scene, editor)
    try:
        with socket.create_connection(server.server_address[:2], timeout=20) as s:
            s.sendall(b"GET / HTTP/1.1\r\n")
            t0 = time.monotonic()
            s.recv(100)  # the server hangs up
            assert time.monotonic() - t0 < 10
        with socket.create_connection(server.server_address[:2], timeout=20) as s:
            port = server.server_address[1]
            s.sendall(f"PUT /api/scene HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Inkwarp-Token: "
                      f"{server.token}\r\nContent-Length: 1000\r\n\r\n{{".encode())
            t0 = time.monotonic()
            s.recv(100)
            assert time.monotonic() - t0 < 10
        assert json.loads(scene.read_text())["width"] == 1
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.parametrize("argv, needle", [
    (["--port", "99999"], "99999 is not a port"),
    (["--port", "-5"], "is not a port"),
])
def test_bad_port_is_a_clean_usage_error(editor: Path, monkeypatch, capsys, argv, needle) -> None:
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    with pytest.raises(SystemExit) as exit_:
        main(["edit", "--no-browser", *argv])
    assert exit_.value.code == 2
    assert needle in capsys.readouterr().err


def test_unknown_host_is_a_clean_error(editor: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    assert main(["edit", "--no-browser", "--host", "nonexistent.invalid"]) == 2
    err = capsys.readouterr().err
    assert "--host nonexistent.invalid" in err and "Traceback" not in err


def _first_url(editor: Path, *argv: str) -> str:
    """The URL `inkwarp edit --no-browser ARGV` prints, the server stopped after."""
    import re
    import subprocess
    import sys

    env = {**os.environ, "INKWARP_EDITOR_DIR": str(editor)}
    proc = subprocess.Popen([sys.executable, "-m", "inkwarp.cli", "edit", "--no-browser", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    with proc, proc.stdout:
        try:
            line = proc.stdout.readline()
        finally:
            proc.kill()
    found = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
    assert found, line
    return found.group(1)


def test_the_editor_keeps_its_port_from_run_to_run_unless_it_is_taken(editor: Path) -> None:
    # The browser keeps unsaved work per origin: the same port each run finds it again.
    from inkwarp.cli.edit import DEFAULT_PORT

    with socket.socket() as probe:
        try:
            probe.bind(("127.0.0.1", DEFAULT_PORT))
        except OSError:
            pytest.skip(f"port {DEFAULT_PORT} is in use on this machine")
    assert _first_url(editor) == str(DEFAULT_PORT)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", DEFAULT_PORT))
        taken.listen()
        assert _first_url(editor) not in ("", str(DEFAULT_PORT))


def test_a_second_editor_says_which_port_it_took_and_that_the_scene_is_served_already(
        editor: Path, scene: Path, monkeypatch, capsys) -> None:
    # Work kept in the browser is kept per address: a run moved off the default port says so,
    # and one whose scene another run already serves there warns.
    import inkwarp.cli.edit as edit

    first = serve(scene, editor)  # another run, on what is the default port here
    port = first.server_address[1]
    monkeypatch.setattr(edit, "DEFAULT_PORT", port)
    monkeypatch.setenv("INKWARP_EDITOR_DIR", str(editor))
    # It prints, then ends at once.
    monkeypatch.setattr(edit.EditorServer, "serve_forever", lambda self, *a, **k: None)
    monkeypatch.setattr(edit.EditorServer, "shutdown", lambda self: None)
    try:
        for argv, warned in (([str(scene)], True), ([], False)):
            assert main(["edit", "--no-browser", *argv]) == 0
            said = capsys.readouterr().out
            moved = re.search(r"http://127\.0\.0\.1:(\d+)/", said).group(1)
            assert moved != str(port)
            assert f"Port {port} is taken" in said and f"serves on port {moved}" in said
            assert "unsaved work per address" in said and "open the address above" in said
            assert ("already serves " + str(scene) in said) == warned, said
    finally:
        monkeypatch.undo()
        first.shutdown()
        first.server_close()


def test_the_serving_probe_tells_only_whether_a_scene_is_served(served, scene: Path) -> None:
    from inkwarp.cli.edit import serving_id

    status, _, body = fetch(api_url(served).replace("scene", "serving"), token=False)
    assert status == 200 and body.decode() == serving_id(scene) and str(scene).encode() not in body


@pytest.mark.parametrize("code, said", [
    (errno.ENOSPC, "the disk is full: no room to write"),
    (errno.EROFS, "is on a read-only file system; not saved"),
])
def test_a_save_on_a_full_or_read_only_disk_says_so(served, scene: Path, monkeypatch, code, said) -> None:
    import inkwarp._atomic

    api = api_url(served)
    doc = json.loads(fetch(api)[2])
    before = scene.read_bytes()
    real = os.replace

    def refuse(src, dst):
        if str(dst) == str(scene):
            raise OSError(code, os.strerror(code))
        return real(src, dst)

    monkeypatch.setattr(inkwarp._atomic.os, "replace", refuse)
    status, _, body = fetch(api, "PUT", json.dumps({**doc, "fps": 12}).encode())
    text = body.decode()
    assert status == 422 and said in text and str(scene) in text and "Errno" not in text, text
    assert "not writable by you" not in text
    assert scene.read_bytes() == before
    assert [p.name for p in scene.parent.iterdir() if p.name.startswith(".")] == []


def test_a_read_only_mount_is_named_as_such_not_as_permissions(served, scene: Path, monkeypatch) -> None:
    import inkwarp.cli.edit as edit

    api = api_url(served)
    doc = json.loads(fetch(api)[2])
    monkeypatch.setattr(edit, "_read_only_fs", lambda folder: True)
    monkeypatch.setattr(edit.os, "access", lambda *a, **k: False)
    status, _, body = fetch(api, "PUT", json.dumps({**doc, "fps": 12}).encode())
    assert status == 422 and b"read-only file system" in body and b"not writable by you" not in body


def test_a_kept_copy_of_a_picture_changed_on_disk_is_written_beside_it(editor: Path, scene: Path) -> None:
    # Work kept in the browser holds the picture as it was; the file changed since (here to
    # another size, which the scene cannot take). Marked by the editor as a kept copy, it is
    # written beside the file under a new name, never inlined in the scene nor mapped back to
    # the changed file, in the run that read both pictures and in a fresh one alike.
    old_uri = DOT_URI
    for fresh in (False, True):
        server = serve(scene, editor)
        try:
            api = api_url(server)
            if not fresh:
                fetch(api)  # this run reads the picture as it was
            from PIL import Image

            Image.new("RGB", (2, 1), (0, 200, 0)).save(scene.parent / "art" / "dot.png")
            doc = json.loads(scene.read_text())
            doc["layers"][0]["image"] = old_uri
            doc["features"] = [{"id": "p", "kind": "point", "rest": [[0, 0]]}]
            body = json.dumps(doc).encode()
            # Unmarked, the run that read the old picture still maps it to the changed file,
            # which no longer fits: refused, nothing written.
            if not fresh:
                status, _, said = fetch(api, "PUT", body)
                assert status == 422 and b"pixels" in said
            status, headers, _ = fetch(api, "PUT", body, headers={"X-Inkwarp-Kept-Copies": "0.image"})
            assert status == 200
            saved = json.loads(scene.read_text())
            name = "art/dot-kept.png" if not fresh else "art/dot-kept-2.png"
            assert saved["layers"][0]["image"] == name, saved["layers"][0]["image"][:40]
            assert (scene.parent / name).read_bytes() == PNG_1x1
            note = urllib.parse.unquote(headers["X-Inkwarp-Note"])
            assert f"written beside it as {name}" in note and "art/dot.png is left as it is" in note
            # A later save of the same scene names the copy by its path, and writes no other.
            status, headers, _ = fetch(api, "PUT", body, headers={"X-Inkwarp-Kept-Copies": "0.image"},
                                       token=TOKEN[0])
            assert status == 200 and "X-Inkwarp-Note" not in headers
            assert json.loads(scene.read_text())["layers"][0]["image"] in (name, "art/dot.png")
        finally:
            server.shutdown()
            server.server_close()
        doc = json.loads(scene.read_text())
        doc["layers"][0]["image"] = "art/dot.png"
        scene.write_text(json.dumps(doc))
        (scene.parent / "art" / "dot.png").write_bytes(PNG_1x1)
