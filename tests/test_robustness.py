"""Nothing crashes, nothing is lost: each case found by probing inkwarp as an attacker and
as a careless user would (issue 45) ends in a clear error, and a failed output leaves no
file under its name."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import inkwarp
from inkwarp.cli import main
from inkwarp.errors import InternalError

SCENE = {"inkwarp": 1, "width": 64, "height": 48, "layers": [{"name": "m"}],
         "features": [{"id": "a", "kind": "point", "rest": [[10, 10]],
                       "keys": [{"t": 0, "points": [[10, 10]]}, {"t": 1, "points": [[14, 12]]}]}]}


def scene_with(tmp_path: Path, name: str, change) -> Path:
    doc = json.loads(json.dumps(SCENE))
    change(doc)
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


CASES = {
    "cut at 1e308": (lambda d: d["features"].append(
        {"id": "c", "kind": "cut", "rest": [[1e308, 0], [-1e308, 5]]}), "features[1].rest[0][0]"),
    "tension 1e300": (lambda d: d.update(solver={"tension": 1e300}), "solver.tension"),
    "point at 2**64": (lambda d: d["features"][0].update(rest=[[2.0 ** 64, 1]]), "features[0].rest[0][0]"),
    "polyline at 1e8": (lambda d: d["features"].append(
        {"id": "p", "kind": "polyline", "rest": [[0, 0], [1e8, 1e8]]}), "features[1].rest[1][0]"),
    "spline at 1e8": (lambda d: d["features"].append(
        {"id": "p", "kind": "spline", "rest": [[0, 0], [1e8, 1], [3, 3]]}), "features[1].rest[1][0]"),
    "key at 1e308": (lambda d: d["features"][0]["keys"].append({"t": 1e308, "points": [[1, 1]]}),
                     "features[0].keys[2].t"),
    "keys 1e-300 apart": (lambda d: d["features"][0]["keys"][1].update(t=1e-300), "features[0].keys[1].t"),
    "beier-neely b 1e308": (lambda d: d.update(solver={"method": "beier-neely",
                                                       "beier_neely": {"b": 1e308}}),
                            "solver.beier_neely.b"),
    "canvas 100000 square": (lambda d: d.update(width=100000, height=100000), "width"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_probed_scenes_fail_cleanly_in_validate_and_render(tmp_path: Path, capsys, case: str) -> None:
    change, where = CASES[case]
    path = scene_with(tmp_path, "s.json", change)
    assert main(["validate", str(path)]) == 2
    out = capsys.readouterr()
    assert where in out.out + out.err and "Traceback" not in out.err
    assert main(["render", str(path), "--time", "0.5", "-o", str(tmp_path / "f.png")]) == 2
    err = capsys.readouterr().err
    assert where in err and "Traceback" not in err and len(err) < 600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]


@pytest.mark.parametrize("name", ["日本.png", "фото.png", "größe.png"])
def test_non_ascii_image_names(tmp_path: Path, name: str) -> None:
    inkwarp.imaging.write_png(tmp_path / name, np.full((48, 64, 4), 200, np.uint8))
    path = scene_with(tmp_path, "s.json", lambda d: d["layers"][0].update(image=name))
    frame = inkwarp.Scene.load(path).render(0.5)
    assert frame.shape == (48, 64, 4)


def test_a_picture_declaring_a_huge_size_is_refused_before_decoding(tmp_path: Path) -> None:
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 12000, 12000, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(b"\0" * 1000)) + chunk(b"IEND", b""))
    (tmp_path / "big.png").write_bytes(png)
    path = scene_with(tmp_path, "s.json", lambda d: (d.pop("width"), d.pop("height"),
                                                     d["layers"][0].update(image="big.png")))
    problems = inkwarp.validate_scene(path)
    assert problems and "12000×12000" in problems[0][1] and "megapixels" in problems[0][1]
    with pytest.raises(inkwarp.SceneError, match="12000×12000"):
        inkwarp.Scene.load(path)


def test_fifos_and_devices_are_refused_not_read(tmp_path: Path, capsys) -> None:
    os.mkfifo(tmp_path / "pipe.png")
    path = scene_with(tmp_path, "s.json", lambda d: d["layers"][0].update(image="pipe.png"))
    assert main(["validate", str(path)]) == 2
    assert "not a regular file" in capsys.readouterr().out
    assert main(["render", "/dev/zero", "-o", str(tmp_path / "z.png")]) == 2
    assert "/dev/zero: not a regular file" in capsys.readouterr().err


def test_byte_order_mark_and_non_utf8(tmp_path: Path, capsys) -> None:
    bom = tmp_path / "bom.json"
    bom.write_text(json.dumps(SCENE), encoding="utf-8-sig")
    assert main(["validate", str(bom)]) == 0
    assert main(["render", str(bom), "--time", "0", "-o", str(tmp_path / "b.png")]) == 0
    latin = tmp_path / "latin.json"
    latin.write_bytes(json.dumps({**SCENE, "layers": [{"name": "X"}]}).replace("X", "\xe9").encode("latin-1"))
    capsys.readouterr()
    assert main(["validate", str(latin)]) == 2
    assert main(["render", str(latin), "-o", str(tmp_path / "l.png")]) == 2
    err = capsys.readouterr()
    assert f"{latin}: not UTF-8 text" in err.out and f"{latin}: not UTF-8 text" in err.err
    # An empty file (a save that did not finish) said "not valid JSON: EOF while parsing".
    empty = tmp_path / "empty.json"
    empty.write_text(" \n")
    assert main(["validate", str(empty)]) == 2
    assert main(["render", str(empty), "-o", str(tmp_path / "e.png")]) == 2
    err = capsys.readouterr()
    assert f"{empty}: the file is empty" in err.out and f"{empty}: the file is empty" in err.err, err
    assert not (tmp_path / "e.png").exists()


def test_a_picture_given_as_the_scene_is_named_a_picture(tmp_path: Path, capsys) -> None:
    from PIL import Image

    Image.new("RGB", (8, 6)).save(tmp_path / "pic.png")
    assert main(["render", str(tmp_path / "pic.png"), "-o", str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert "pic.png: a PNG picture, not a scene; make a scene of it with inkwarp new" in err, err
    assert not (tmp_path / "o.png").exists()
    # An SVG drawing given as the scene said only "not valid JSON".
    (tmp_path / "tracing.svg").write_text('<?xml version="1.0"?>\n<svg xmlns="http://www.w3.org/2000/svg"/>')
    assert main(["render", str(tmp_path / "tracing.svg"), "-o", str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert f"tracing.svg: an SVG drawing, not a scene; trace it over its picture into a scene with inkwarp new PICTURE --drawing {tmp_path / 'tracing.svg'}" in err, err
    # A HEIC photo (an ISO media file, as MP4 is) is a picture, not a video.
    (tmp_path / "photo.heic").write_bytes(b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00mif1heic" + bytes(200) + b"\xff")
    assert main(["validate", str(tmp_path / "photo.heic")]) == 2
    assert "photo.heic: a HEIC picture, not a scene" in capsys.readouterr().out
    # A video given as the scene said "not UTF-8 text (byte 43, line 1)".
    from inkwarp.video import write_frames

    for name, kind in (("clip.mp4", "an MP4 video"), ("clip.webm", "a WebM video")):
        write_frames(tmp_path / name, [np.full((32, 32, 4), 255, np.uint8)] * 4, fps=4)
        assert main(["track", str(tmp_path / name), "--scene", str(tmp_path / name), "-o", str(tmp_path / "t.json")]) == 2
        err = capsys.readouterr().err
        assert f"{name}: {kind}, not a scene; a scene is a JSON file" in err, err
        assert f"inkwarp track {tmp_path / name} --scene SCENE" in err and not (tmp_path / "t.json").exists(), err


@pytest.mark.parametrize("number", ["NaN", "Infinity", "-Infinity"])
def test_nan_in_a_scene_file_is_named_as_such(tmp_path: Path, capsys, number) -> None:
    path = tmp_path / "nan.json"
    doc = {**SCENE, "features": [{"id": "p", "kind": "point", "rest": [[1.0, 123456.0]]}]}
    path.write_text(json.dumps(doc).replace("123456.0", number))
    assert main(["validate", str(path)]) == 2
    out = capsys.readouterr().out
    assert "not valid JSON" in out and "NaN and Infinity are not JSON numbers" in out, out


@pytest.mark.parametrize("shape", [(2 ** 62, 4), (20000, 20000), (10000, 10000), (2 ** 64, 4)])
def test_thin_plate_refuses_grids_beyond_the_limits(shape) -> None:
    with pytest.raises(ValueError, match="at most|megapixels"):
        inkwarp.thin_plate(np.array([[1.0, 1.0]]), np.array([[1.0, 0.0]]), shape=shape)


def test_huge_displacements_are_refused_not_turned_into_nan() -> None:
    with pytest.raises(ValueError, match="within"):
        inkwarp.thin_plate(np.array([[1.0, 1.0]]), np.array([[1e300, 0.0]]), shape=(8, 8))


def test_a_panic_in_the_engine_is_an_internal_error(monkeypatch, tmp_path: Path, capsys) -> None:
    from inkwarp import _inkwarp

    with pytest.raises(InternalError, match="on purpose.*please report"):
        _inkwarp._panic_for_tests()
    assert issubclass(InternalError, inkwarp.InkwarpError)

    def load(path):
        _inkwarp._panic_for_tests()

    monkeypatch.setattr(inkwarp.Scene, "load", staticmethod(load))
    path = scene_with(tmp_path, "s.json", lambda d: None)
    assert main(["render", str(path), "-o", str(tmp_path / "x.png")]) == 1
    err = capsys.readouterr().err
    assert "please report" in err and "Traceback" not in err


FULL_DISK = """
import resource, sys
import numpy as np
from inkwarp.cli import main
resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))
sys.exit(main(["render", sys.argv[1], "-o", sys.argv[2]]))
"""


def test_a_full_disk_during_mp4_is_exit_1_with_no_file(tmp_path: Path) -> None:
    path = scene_with(tmp_path, "s.json", lambda d: d.update(width=320, height=240, duration=2))
    inkwarp.imaging.write_png(tmp_path / "noise.png",
                              np.random.default_rng(0).integers(0, 255, (240, 320, 4), np.uint8))
    path.write_text(json.dumps({**json.loads(path.read_text()),
                                "layers": [{"name": "m", "image": "noise.png"}]}))
    out = tmp_path / "clip.mp4"
    run = subprocess.run([sys.executable, "-c", FULL_DISK, str(path), str(out)],
                         capture_output=True, text=True, timeout=120,
                         preexec_fn=lambda: signal.signal(signal.SIGXFSZ, signal.SIG_IGN))
    assert run.returncode == 1, run.stderr
    assert "file-size limit" in run.stderr and str(out) in run.stderr and "Traceback" not in run.stderr
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


INTERRUPT = """
import sys, time, numpy as np, inkwarp
print("ready", flush=True)
rng = np.random.default_rng(1)
pts = rng.uniform(0, 1500, (4000, 2))
try:
    inkwarp.interpolate(pts, rng.normal(0, 3, (4000, 2)), (1500, 1500), method="tps-exact",
                        max_samples=4000)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(130)
print("finished", flush=True)
"""


def seconds_to_stop_after_ctrl_c(script: str, running_s: float, timeout_s: float) -> float:
    """Run ``script`` in a new Python, send it SIGINT ``running_s`` after it prints
    "ready", check it stopped as interrupted (exit 130), and return how long that took."""
    # SIGINT back to its default in the child: a test run started in the background (where
    # the shell ignores SIGINT, and children inherit that) still sees Ctrl-C as a user would.
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(running_s)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()  # not left running past a failed test
        proc.communicate()
        raise
    stopped_s = time.monotonic() - sent
    assert out.strip() == "interrupted" and proc.returncode == 130
    return stopped_s


def test_ctrl_c_stops_a_long_dense_solve_within_a_second() -> None:
    stopped_s = seconds_to_stop_after_ctrl_c(INTERRUPT, running_s=1.5, timeout_s=30)
    assert stopped_s < 5  # generous for a loaded machine; the flag is polled every 50 ms


GRID_INTERRUPT = """
import sys, numpy as np, inkwarp
n = 1025
rng = np.random.default_rng(2)
mask = np.ones((n, n), np.uint8)
yy, xx = np.mgrid[:n, :n]
mask[(xx - 650) ** 2 + (yy - 400) ** 2 < 75 ** 2] = 0
pts = rng.uniform(0, n - 1, (10, 2))
args = dict(mask=mask, cuts=[[(100, 700.3), (450, 625.3), (800, 750.3)]], tolerance=1e-12)
# One cycle first, so that the long solve below is in its cycles (not in the setup of its
# hierarchy, which is not interruptible) when the signal comes.
inkwarp.thin_plate_report(pts, rng.normal(0, 5, (10, 2)), (n, n), max_cycles=1, **args)
print("ready", flush=True)
try:
    # A tolerance it cannot reach and no cycle limit worth the name: it runs until stopped.
    inkwarp.thin_plate_report(pts, rng.normal(0, 5, (10, 2)), (n, n), max_cycles=100000, **args)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(130)
print("finished", flush=True)
"""


def test_ctrl_c_stops_a_long_grid_solve_within_a_second() -> None:
    stopped_s = seconds_to_stop_after_ctrl_c(GRID_INTERRUPT, running_s=2, timeout_s=60)  # cycles running
    assert stopped_s < 5  # generous for a loaded machine; the solver checks between cycles


WARP_INTERRUPT = """
import sys, numpy as np, inkwarp
rng = np.random.default_rng(3)
image = rng.integers(0, 256, (800, 800, 4), np.uint8)
# A field of noise hundreds of pixels wide (a user's mistake): every quad spans much of the
# canvas, so the draw takes hours.
field = rng.normal(0, 300, (800, 800, 2)).astype(np.float32)
print("ready", flush=True)
try:
    inkwarp.warp_image(image, field)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(130)
print("finished", flush=True)
"""


def test_ctrl_c_stops_a_long_warp_within_a_second() -> None:
    stopped_s = seconds_to_stop_after_ctrl_c(WARP_INTERRUPT, running_s=2, timeout_s=60)
    assert stopped_s < 5  # generous for a loaded machine; the draw checks every mesh row


def test_compare_refuses_an_absurd_dpi(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["compare", "examples/face/scene.json", "--dpi", "100000", "-o", "x.png"])
    assert exit_.value.code == 2
    assert "100000: give a whole number of dots per inch from 10 to 600" in capsys.readouterr().err


def test_the_gif_writer_streams_frames_to_disk(tmp_path: Path) -> None:
    from PIL import Image

    from inkwarp.video import open_writer

    rng = np.random.default_rng(0)
    frames = []
    sizes = []
    out = tmp_path / "clip.gif"
    with open_writer(out, fps=24) as writer:
        for k in range(6):
            frame = rng.integers(0, 255, (20, 33, 4), np.uint8)
            frame[..., 3] = 255
            frames.append(frame)
            writer.write(frame)
            sizes.append(sum(p.stat().st_size for p in tmp_path.iterdir()))
    # Each frame is on disk once the next is written (the last one is held, to merge a
    # run of equal frames; nothing is held for the end).
    assert all(b > a for a, b in zip(sizes, sizes[1:]))
    with Image.open(out) as gif:
        assert gif.n_frames == 6 and gif.info["loop"] == 0 and gif.size == (33, 20)
        for i, frame in enumerate(frames):
            gif.seek(i)
            assert gif.info["duration"] in (40, 50)
            # Exactly the frame as quantised to its own palette (255 colours and the
            # transparent index).
            quantised = Image.fromarray(frame[..., :3]).quantize(
                colors=255, method=Image.Quantize.FASTOCTREE).convert("RGB")
            assert np.array_equal(np.asarray(gif.convert("RGB")), np.asarray(quantised))
    assert [p.name for p in tmp_path.iterdir()] == ["clip.gif"]


FORKED = """
import multiprocessing as mp, sys
import numpy as np, inkwarp

def job(kind):
    pts, disp = [[5.0, 5.0], [50.0, 40.0], [30.0, 10.0]], [[1.0, 0.0], [0.0, 2.0], [-1.0, 1.0]]
    if kind == "thin_plate":
        return inkwarp.thin_plate(pts, disp, (64, 64)).tobytes()
    if kind == "warp_image":
        field = inkwarp.thin_plate(pts, disp, (64, 64))
        return inkwarp.warp_image(np.full((64, 64, 4), 200, np.uint8), field).tobytes()
    if kind == "scene":
        return inkwarp.Scene.load(sys.argv[1]).render(time=0.5).tobytes()
    if kind == "frames":  # past one chain of frames, on two threads: the stream's own workers
        return b"".join(frame.tobytes() for frame in inkwarp.Scene.load(sys.argv[1]).frames(0, 40, threads=2))
    if kind == "map":  # enough points for the fit's parallel solve
        grid = np.stack(np.meshgrid(np.arange(12.0), np.arange(12.0)), -1).reshape(-1, 2) * 5
        return np.asarray(inkwarp.ThinPlateMap(grid, grid + 1.5)(grid[:7] + 0.5)).tobytes()

if __name__ == "__main__":
    kinds = ["thin_plate", "warp_image", "scene", "frames", "map"]
    here = [job(k) for k in kinds]  # the engine runs in the parent first
    with mp.get_context("fork").Pool(2) as pool:
        there = pool.map_async(job, kinds).get(timeout=120)
    assert here == there, [k for k, a, b in zip(kinds, here, there) if a != b]
    print("forked: same")
"""


def test_the_engine_works_in_processes_forked_after_it_ran(tmp_path: Path) -> None:
    # multiprocessing's default start method on Linux forks, and a fork copies the engine's
    # thread pool without its threads: each process needs its own.
    script = tmp_path / "forked.py"
    script.write_text(FORKED)
    scene = Path(__file__).resolve().parent.parent / "examples" / "cat" / "scene.json"
    done = subprocess.run([sys.executable, str(script), str(scene)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "forked: same" in done.stdout


def test_wrong_argument_types_are_value_errors_naming_the_argument(tmp_path: Path) -> None:
    # docs/reference/limits.md: a wrong argument is a ValueError naming it, never a bare
    # TypeError or AttributeError from inside (pathlib's, the engine's, matplotlib's).
    import inkwarp

    scene = inkwarp.Scene.from_dict({"inkwarp": 1, "width": 8, "height": 8, "layers": [{"name": "main"}]})
    for call, named in [(lambda: inkwarp.Scene.new(None), "picture"),
                        (lambda: inkwarp.validate_scene(None), "source"),
                        (lambda: inkwarp.Scene.from_json(None), "text"),
                        (lambda: inkwarp.Scene.from_json("{}", base_dir=5), "base_dir"),
                        (lambda: inkwarp.compare(scene, 0.0, 5), "methods"),
                        (lambda: inkwarp.comparison_sheet(None), "comparison"),
                        (lambda: inkwarp.transfer_dict(scene, scene, relative_to=5), "relative_to")]:
        with pytest.raises(ValueError, match=rf"^{named}\b"):
            call()
    # A scene's JSON as bytes, as a file is read, is taken.
    assert inkwarp.Scene.from_json(b'{"inkwarp": 1, "width": 8, "height": 8, "layers": [{"name": "m"}]}').width == 8


def test_every_refusal_of_the_api_is_an_inkwarp_error_and_a_value_error(tmp_path: Path) -> None:
    # A pipeline catches `inkwarp.InkwarpError`, as its docstring invites ("every error
    # inkwarp raises on purpose"): a layer name that is not there, a frame range, an output's
    # extension and the grid solve's argument checks (in Python and in the engine) raised
    # plain ValueErrors that it let through.
    scene = inkwarp.Scene.load(scene_with(tmp_path, "s.json", lambda d: None))
    refusals = {
        "layer": lambda: scene.field(time=0.5, layer="nope"),
        "frames": lambda: list(scene.frames(5, 2)),
        "extension": lambda: inkwarp.render(scene, tmp_path / "out.xyz"),
        "shape": lambda: inkwarp.thin_plate([[1, 1]], [[1, 1]], (0, 5)),
        "tolerance": lambda: inkwarp.thin_plate([[1, 1]], [[1, 1]], (8, 8), tolerance=float("nan")),
        "engine": lambda: inkwarp.thin_plate([[1e12, 1]], [[1, 1]], (8, 8)),
        "warp": lambda: inkwarp.warp_image(np.zeros((8, 8, 4), np.uint8), np.full((8, 8, 2), np.nan)),
        "frames text": lambda: inkwarp.render(scene, tmp_path / "a.gif", frames="x"),
    }
    for name, refused in refusals.items():
        with pytest.raises(inkwarp.InkwarpError) as caught:
            refused()
        assert isinstance(caught.value, ValueError) and type(caught.value).__name__ in ("InputError", "SceneError"), (
            name, type(caught.value))


def test_a_missing_file_is_an_inkwarp_error_and_a_file_not_found_error(tmp_path: Path) -> None:
    # Scene.load, Scene.new (picture, PSD, drawing), read_image, track, transfer and a save
    # into a folder that does not exist raised bare FileNotFoundErrors, which a pipeline's
    # `except inkwarp.InkwarpError` let through.
    scene = inkwarp.Scene.load(scene_with(tmp_path, "s.json", lambda d: None))
    gone = tmp_path / "gone"
    missing = {
        "load": lambda: inkwarp.Scene.load(gone / "scene.json"),
        "new": lambda: inkwarp.Scene.new(gone / "picture.png"),
        "psd": lambda: inkwarp.Scene.new(gone / "layers.psd"),
        "image": lambda: inkwarp.imaging.read_image(gone / "picture.png"),
        "track": lambda: inkwarp.track(gone / "clip.mp4", scene),
        "transfer": lambda: inkwarp.transfer(gone / "a.json", gone / "b.json"),
        "save": lambda: scene.save(gone / "out.json"),
    }
    for name, refused in missing.items():
        with pytest.raises(inkwarp.InkwarpError) as caught:
            refused()
        assert isinstance(caught.value, FileNotFoundError) and str(gone) in str(caught.value), (name, caught.value)
    assert not gone.exists()
