"""The wheel `make wheel` builds works on its own: installed in a fresh virtualenv whose PATH
holds no Rust and no Node (only the virtualenv), `inkwarp demo`, `inkwarp render` and
`inkwarp edit --no-browser` work. Run by `make test-wheel` after the wheel is built (it is
not in `tests/`'s default collection because it needs the wheel)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
import venv
import zipfile
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]


def wheel() -> Path:
    wheels = sorted((ROOT / "target" / "wheels").glob("inkwarp-*.whl"),
                    key=lambda p: p.stat().st_mtime)
    assert wheels, "no wheel in target/wheels: run `make wheel`"
    return wheels[-1]


def test_the_wheel_ships_the_editor_the_examples_and_the_license():
    names = zipfile.ZipFile(wheel()).namelist()
    assert "inkwarp/editor/index.html" in names
    assert "inkwarp/examples/face/scene.json" in names and "inkwarp/examples/face/face.png" in names
    assert any(n.startswith("inkwarp/_inkwarp") and n.endswith(".so") for n in names)
    metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
    text = zipfile.ZipFile(wheel()).read(metadata).decode()
    assert "License :: OSI Approved :: MIT License" in text
    assert "Provides-Extra: ray" in text and "Project-URL: Source" in text


def test_a_fresh_virtualenv_with_only_the_wheel_runs_demo_render_and_edit(tmp_path):
    env_dir = tmp_path / "env"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    bin_dir = env_dir / "bin"
    # Only the virtualenv on PATH: no cargo, no rustc, no node, no npm.
    env = {"PATH": str(bin_dir), "HOME": os.environ.get("HOME", str(tmp_path)),
           "PIP_DISABLE_PIP_VERSION_CHECK": "1", "LANG": "C.UTF-8"}
    for key in ("PIP_INDEX_URL", "PIP_EXTRA_INDEX_URL", "PIP_CACHE_DIR", "PIP_FIND_LINKS"):
        if key in os.environ:
            env[key] = os.environ[key]
    subprocess.run([bin_dir / "python", "-m", "pip", "install", "-q", str(wheel())],
                   check=True, env=env, cwd=tmp_path, timeout=600)
    for tool in ("cargo", "rustc", "node", "npm"):
        assert shutil.which(tool, path=env["PATH"]) is None

    inkwarp = str(bin_dir / "inkwarp")
    demo = subprocess.run([inkwarp, "demo", "-o", "out", "--only", "face", "--formats", "gif"],
                          env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert demo.returncode == 0, demo.stderr
    assert (tmp_path / "out" / "face.gif").is_file()

    scene_src = Path(subprocess.run(
        [bin_dir / "python", "-c", "import inkwarp.demo as d; print(d.find_examples())"],
        env=env, capture_output=True, text=True, check=True).stdout.strip())
    assert scene_src.is_relative_to(env_dir)  # the wheel's copy, not this checkout's
    render = subprocess.run([inkwarp, "render", str(scene_src / "face" / "scene.json"), "-o",
                             str(tmp_path / "f.png"), "--frame", "3"], env=env,
                            capture_output=True, text=True, timeout=300)
    assert render.returncode == 0, render.stderr
    assert np.asarray(Image.open(tmp_path / "f.png")).shape[2] == 4

    # PYTHONFAULTHANDLER: should it not stop, SIGABRT prints its Python threads' stacks.
    edit = subprocess.Popen([inkwarp, "edit", "--no-browser", "--port", "0"], cwd=tmp_path,
                            env={**env, "PYTHONFAULTHANDLER": "1"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = edit.stdout.readline()
        assert line.startswith("inkwarp editor at http://127.0.0.1:"), (line, edit.stderr.read()
                                                                      if edit.poll() else "")
        url = line.split(" at ", 1)[1].split()[0]
        deadline = time.monotonic() + 30
        while True:
            try:
                page = urllib.request.urlopen(url, timeout=10).read().decode()
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        assert "<script" in page and "inkwarp" in page.lower()
    finally:
        edit.terminate()
        try:
            edit.communicate(timeout=30)  # waits, and closes the pipes
        except subprocess.TimeoutExpired:
            edit.send_signal(signal.SIGABRT)
            try:
                _, err = edit.communicate(timeout=30)
            finally:
                edit.kill()
            raise AssertionError(f"inkwarp edit still ran 30 s after SIGTERM; its Python threads:\n{err}")


if __name__ == "__main__":
    sys.exit(subprocess.call([sys.executable, "-m", "pytest", __file__]))
