"""`inkwarp demo`: the stills and an example, every path printed; its mistakes exit 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from inkwarp import demo
from inkwarp.cli import main


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_stills_are_written_and_printed(capsys, tmp_path):
    code, stdout, _ = run(capsys, "demo", "-o", tmp_path / "out", "--only", "stills")
    assert code == 0
    names = ["before.png", "matte.png", "after.png", "field.png"]
    for name in names:
        assert f"{tmp_path / 'out' / name}\n" in stdout
    before = np.asarray(Image.open(tmp_path / "out" / "before.png"))
    assert (before == demo.still_picture()).all()
    after = np.asarray(Image.open(tmp_path / "out" / "after.png"))
    assert after.shape == (demo.STILL_SIZE[1], demo.STILL_SIZE[0], 4)
    assert np.abs(after[..., :3].astype(int) - before[..., :3]).mean() > 5  # it moved
    matte = np.asarray(Image.open(tmp_path / "out" / "matte.png"))
    x0, x1, y0, y1 = demo._still_slot(*demo.STILL_SIZE)
    assert (matte[y0:y1, x0:x1, :3] == 0).all() and matte[5, 5].min() == 255
    field = np.asarray(Image.open(tmp_path / "out" / "field.png"))
    assert field.shape[:2] == after.shape[:2] and field[..., :3].std() > 10


def test_still_scene_moves_the_curve_where_it_is_keyed(tmp_path):
    import inkwarp

    demo.stills(tmp_path)
    scene = inkwarp.Scene.from_dict(demo.still_scene(), base_dir=str(tmp_path))
    field = scene.field(time=1.0)
    rest, pose = demo._still_curve(*demo.STILL_SIZE)
    x, y = np.round(rest[2]).astype(int)
    assert np.allclose(field[y, x], pose[2] - rest[2], atol=0.75)
    assert np.abs(field[0, :]).max() < 0.5  # the border is held


def test_an_example_renders_to_every_format_asked(capsys, tmp_path):
    """The demo's plumbing, on small stand-ins for the examples (`make demo` renders the
    real ones): every scene of the example, each format, every path printed."""
    from _cli_scenes import write_scene

    examples = tmp_path / "examples"
    write_scene(examples / "face")  # the marker find_examples looks for
    for scene in demo.EXAMPLES["checkerboard-hole"]:
        write_scene(examples / "checkerboard-hole", name=scene)
    out = tmp_path / "out"
    code, stdout, _ = run(capsys, "demo", "-o", out, "--only", "checkerboard-hole",
                          "--examples", examples, "-q")
    assert code == 0
    names = [f"checkerboard-hole-{stem}.{fmt}" for stem in ("with-hole", "without-hole")
             for fmt in ("gif", "mp4")]
    for name in names:
        assert f"{out / name}\n" in stdout
    assert sorted(p.name for p in out.iterdir()) == sorted(names)
    with Image.open(out / "checkerboard-hole-with-hole.gif") as gif:
        assert gif.n_frames == 4
    assert "4 frames of 48x40 at 4 fps in" in stdout


def test_each_progress_bar_is_named_by_what_it_writes(capsys, tmp_path):
    # Two scenes of one folder were both "checkerboard-hole:" (and the transfer and rotoscope
    # results, made in the demo's own folder, both "demo:").
    from _cli_scenes import write_scene

    examples = tmp_path / "examples"
    write_scene(examples / "face")
    for scene in demo.EXAMPLES["checkerboard-hole"]:
        write_scene(examples / "checkerboard-hole", name=scene)
    code, _, stderr = run(capsys, "demo", "-o", tmp_path / "out", "--only", "checkerboard-hole",
                          "--examples", examples, "--formats", "gif")
    assert code == 0
    assert "checkerboard-hole-with-hole:" in stderr and "checkerboard-hole-without-hole:" in stderr, stderr


@pytest.mark.parametrize("args, expected", [
    (["--formats", "webm"], "unknown format 'webm'"),
    # Not "pass --examples DIR", which it was given.
    (["--only", "face", "--examples", "{tmp}"], "no example scenes there (face/scene.json is missing); "
                                                "give the examples/ folder of a source checkout"),
])
def test_demo_mistakes_exit_2(capsys, tmp_path, args, expected):
    args = [a.format(tmp=tmp_path) for a in args]
    code, _, stderr = run(capsys, "demo", "-o", tmp_path / "out", *args)
    assert code == 2 and expected in stderr and len(stderr.splitlines()) == 1


def test_every_example_scene_is_valid(capsys):
    root = Path(__file__).resolve().parents[1] / "examples"
    for name, scenes in demo.EXAMPLES.items():
        for scene in scenes:
            code, stdout, _ = run(capsys, "validate", root / name / scene)
            assert code == 0 and stdout.startswith("ok: "), (name, scene, stdout)


def test_a_warning_along_the_way_is_one_line(capsys, tmp_path, monkeypatch):
    # The rotoscope example's lost track came out as a Python warning: the launcher's path
    # and line, then its source line.
    import warnings

    from inkwarp.errors import InkwarpWarning

    def run_with_a_warning(out, **_):
        warnings.warn("actor.mp4: lost track of 'head' at frame 55", InkwarpWarning, stacklevel=2)

    monkeypatch.setattr(demo, "run", run_with_a_warning)
    code, _, stderr = run(capsys, "demo", "-o", tmp_path / "out")
    assert code == 0
    assert stderr == "inkwarp demo: warning: actor.mp4: lost track of 'head' at frame 55\n"
