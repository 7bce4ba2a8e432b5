"""Bad input exits 2 with one line naming the file, the JSON path and the fix; a bug exits
1; a failed or interrupted render leaves nothing behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from _cli_scenes import leftovers, mutated, write_scene
from inkwarp.cli import main


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _set(path, value):
    """A change to square_doc(): set the value at a path of keys and indices."""
    def change(doc):
        node = doc
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return change


def _add_feature(feature):
    def change(doc):
        doc["features"].append(feature)
    return change


def _add_layer(image):
    def change(doc):
        doc["layers"].append({"name": "second", "image": image})
    return change


# (what is wrong, the scene, files to write beside it, the JSON path the message names)
MISTAKES = [
    ("unknown kind", mutated(_set(["features", 0, "kind"], "circle")), {},
     "features[0].kind"),
    ("wrong point count in a key", mutated(_set(["features", 0, "keys", 1, "points"],
                                                [[1, 1], [2, 2]])), {},
     "features[0].keys[1].points"),
    ("keys out of order", mutated(_set(["features", 0, "keys", 1, "t"], -0.5)), {},
     "features[0].keys[1].t"),
    ("keys at equal times", mutated(_set(["features", 0, "keys", 1, "t"], 0.0)), {},
     "features[0].keys[1].t"),
    ("unknown feature id in a layer", mutated(_set(["layers", 0, "features"], ["grip", "gripp"])),
     {}, "layers[0].features[1]"),
    ("negative tension", mutated(_set(["solver"], {"tension": -1.0})), {}, "solver.tension"),
    ("zero fps", mutated(_set(["fps"], 0)), {}, "fps"),
    ("unknown method", mutated(_set(["solver"], {"method": "rbf"})), {}, "solver.method"),
    ("misspelt key", mutated(_set(["layers", 0, "colour"], "red")), {}, "layers[0].colour"),
    ("missing image", mutated(_set(["layers", 0, "image"], "nowhere.png")), {},
     "layers[0].image"),
    ("unreadable image", mutated(_set(["layers", 0, "image"], "notes.png")),
     {"notes.png": b"these are not pixels"}, "layers[0].image"),
    ("image of another size", mutated(_add_layer("small.png")), {"small.png": (20, 20)},
     "layers[1].image"),
    ("matte of another size", mutated(_set(["layers", 0, "continuity"], "small.png")),
     {"small.png": (20, 20)}, "layers[0].continuity"),
    # A cut moves nothing: keys on it did nothing, silently; one of zero length tore nothing.
    ("keys on a cut", mutated(_add_feature({
        "id": "slit", "kind": "cut", "rest": [[2.5, 3.5], [9.5, 3.5]],
        "keys": [{"t": 0, "points": [[2.5, 3.5], [9.5, 6.5]]}]})), {}, "features[1].keys"),
    ("a cut of zero length", mutated(_add_feature({
        "id": "slit", "kind": "cut", "rest": [[2.5, 3.5], [2.5, 3.5]]})), {}, "features[1].rest"),
]


def _write_files(directory: Path, files):
    for name, content in files.items():
        if isinstance(content, bytes):
            (directory / name).write_bytes(content)
        else:
            w, h = content
            Image.fromarray(np.full((h, w, 4), 255, np.uint8)).save(directory / name)


@pytest.mark.parametrize("what, doc, files, json_path", MISTAKES, ids=[m[0] for m in MISTAKES])
@pytest.mark.parametrize("command", ["render", "validate"])
def test_each_mistake_gets_one_clear_line(capsys, tmp_path, command, what, doc, files,
                                          json_path):
    scene = write_scene(tmp_path / "s", doc)
    _write_files(scene.parent, files)
    out = tmp_path / "anim.gif"
    args = ["render", scene, "-o", out] if command == "render" else ["validate", scene]
    code, stdout, stderr = run(capsys, *args)
    assert code == 2
    if command == "render":
        lines = stderr.splitlines()
        assert len(lines) == 1, stderr
        line = lines[0]
        assert line.startswith(f"inkwarp render: error: {scene}: {json_path}: "), line
        assert not out.exists() and leftovers(tmp_path) == []
    else:
        assert f"{scene}: {json_path}: " in stdout, stdout
        assert stderr == f"{scene}: 1 problem\n"
    assert "Traceback" not in stdout + stderr
    message = (stdout + stderr).split(f"{json_path}: ", 1)[1]
    assert len(message.split()) >= 3, message  # a sentence, not a code


def test_a_reader_that_goes_away_ends_the_command_quietly(tmp_path):
    # `inkwarp validate many.json | head -1`: the rest of the lines met a closed pipe, and
    # the command said "error: [Errno 32] Broken pipe" with exit status 1.
    import json

    doc = {"inkwarp": 1, "width": 8, "height": 8, "layers": [{"name": "a"}],
           "features": [{"id": f"f{i}", "kind": "splin", "rest": [[1, 1], [2, 2]]} for i in range(3000)]}
    (tmp_path / "many.json").write_text(json.dumps(doc))
    command = [sys.executable, "-c", "import sys; from inkwarp.cli import main; sys.exit(main())",
               "validate", str(tmp_path / "many.json")]
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE) as child:
        assert child.stdout.readline().startswith(str(tmp_path / "many.json").encode())
        child.stdout.close()
        err = child.stderr.read().decode()
        assert child.wait(timeout=60) == 141 and err == "", err


def test_validate_lists_every_problem(capsys, tmp_path):
    def many(doc):
        doc["fps"] = 0
        doc["features"][0]["kind"] = "circle"
        doc["solver"] = {"tension": -1}
    scene = write_scene(tmp_path, mutated(many))
    code, stdout, stderr = run(capsys, "validate", scene)
    assert code == 2
    lines = stdout.splitlines()
    assert sorted(line.split(": ")[1] for line in lines) == ["features[0].kind", "fps",
                                                            "solver.tension"]
    assert "3 problems" in stderr
    # render names the first and says how to see the rest, on one line
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "x.gif")
    assert code == 2 and len(stderr.splitlines()) == 1
    assert f"(and 2 more problems: 'inkwarp validate {scene}' lists all)" in stderr


@pytest.mark.parametrize("text, expected", [
    ('{"inkwarp": 1, "layers": [}', "not valid JSON"),
    ('{"inkwarp": 1, "fps": 1e999, "layers": []}', "not valid JSON"),  # not a finite number
])
def test_broken_json_names_the_file_and_where(capsys, tmp_path, text, expected):
    scene = write_scene(tmp_path, text)
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "x.png")
    assert code == 2
    assert stderr.startswith(f"inkwarp render: error: {scene}: ") and expected in stderr
    assert "line 1" in stderr and len(stderr.splitlines()) == 1


def test_a_key_given_twice_is_refused_where_it_stands(capsys, tmp_path):
    # JSON readers keep the last of two equal keys silently, so a hand edit ("fps": 24 ...
    # "fps": 12) was lost without a word.
    import inkwarp

    text = ('{"inkwarp": 1, "width": 8, "fps": 24, "height": 8, "fps": 12, '
            '"layers": [{"name": "a", "solver": {"tension": 1, "tension": 2}}]}')
    scene = write_scene(tmp_path, text)
    code, stdout, _ = run(capsys, "validate", scene)
    assert code == 2
    assert sorted(line.split(": ")[1] for line in stdout.splitlines()) == ["fps", "layers[0].solver.tension"]
    assert "given more than once" in stdout and "keep one" in stdout
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "x.png")
    assert code == 2 and f"{scene}: fps: given more than once" in stderr and not (tmp_path / "x.png").exists()
    with pytest.raises(inkwarp.SceneError) as err:
        inkwarp.Scene.from_json(text)
    assert err.value.path == "fps" and len(err.value.problems) == 2
    # The same keys in different objects are fine.
    assert inkwarp.validate_scene(tmp_path / "ok.json") == [("", f"no such scene file: {tmp_path / 'ok.json'}")]
    ok = write_scene(tmp_path / "ok", '{"inkwarp": 1, "width": 8, "height": 8, '
                                      '"layers": [{"name": "a"}, {"name": "b"}]}')
    assert inkwarp.validate_scene(ok) == []


def test_missing_scene_file(capsys, tmp_path):
    code, _, stderr = run(capsys, "render", tmp_path / "nope.json", "-o", tmp_path / "x.gif")
    assert code == 2
    assert stderr == f"inkwarp render: error: {tmp_path / 'nope.json'}: no such file or directory\n"


@pytest.mark.parametrize("args, expected", [
    (["-o", "{tmp}/x.avi"], "cannot write '.avi' files"),
    (["-o", "{tmp}/x.json"], "x.json: a .json name is a scene, not an output; name the output .png (one frame), .gif, .mp4, .webm, .mov, .apng, or a folder of PNG frames (end it with /); such as x.gif"),
    (["-o", "{tmp}/missing/x.gif"], "does not exist; create it first"),
    (["-o", "{tmp}/x.gif", "--time", "1"], "--time picks one frame"),
    (["-o", "{tmp}/x.png", "--frames", "0:2"], "a .png holds one frame"),
    (["-o", "{tmp}/x.gif", "--frames", "4:99"], "--frames 4:99 is not a range of the scene, which has frames 0 to 3"),
    (["-o", "{tmp}/x.gif", "--frames", "4:"], "--frames 4: is not a range of the scene"),
    # (A range starting with a minus sign, which the parser took for an option.)
    (["-o", "{tmp}/x.gif", "--frames", "-5:3"], "--frames -5:3 is not a range of the scene, which has frames 0 to 3"),
    (["-o", "{tmp}/x.gif", "--frames", "2"], "write a range A:B"),
    (["-o", "{tmp}/x.png", "--frame", "4"], "the scene has frames 0 to 3"),
    (["-o", "{tmp}/x.png", "--time", "nan"], "give a time in seconds"),
    (["-o", "{tmp}/x.png", "--time", "-200000"], "--time -200000: give a time in seconds from -100000 to 100000"),
    (["-o", "{tmp}/x.png", "--time", "2e5"], "--time 200000: give a time in seconds from -100000 to 100000"),
    # (A negative number with an exponent, which the parser took for an option.)
    (["-o", "{tmp}/x.png", "--time", "-1e6"], "--time -1e+06: give a time in seconds from -100000 to 100000"),
    (["-o", "{tmp}/x.png", "--time", "-inf"], "--time -inf: give a time in seconds"),
    (["-o", "{tmp}/x.png", "--background", ""], "--background '': give transparent, white"),
])
def test_bad_options_say_what_to_do(capsys, tmp_path, args, expected):
    scene = write_scene(tmp_path / "s")
    args = [a.format(tmp=tmp_path) for a in args]
    code, _, stderr = run(capsys, "render", scene, *args)
    assert code == 2 and expected in stderr and len(stderr.splitlines()) == 1, stderr
    assert leftovers(tmp_path) == [] and not any(tmp_path.glob("x.*"))


def test_an_unknown_option_is_named_by_its_command(capsys, tmp_path):
    # It was the top level's error (`inkwarp: error: unrecognized arguments: --fps 12`), with
    # the top level's usage, which does not show render's options.
    scene = write_scene(tmp_path / "s")
    for extra in (["--fps", "12"], [str(scene)]):
        with pytest.raises(SystemExit) as exit:
            main(["render", str(scene), "-o", str(tmp_path / "x.gif"), *extra])
        stderr = capsys.readouterr().err
        assert exit.value.code == 2 and f"inkwarp render: error: unrecognized arguments: {' '.join(extra)}" in stderr, stderr
        assert "usage: inkwarp render" in stderr and not any(tmp_path.glob("x.*")), stderr
    # One before the command is the top level's.
    with pytest.raises(SystemExit):
        main(["--bogus", "validate", str(scene)])
    assert "inkwarp: error: unrecognized arguments: --bogus" in capsys.readouterr().err


def test_a_frame_range_past_the_end_is_cut_to_it_with_a_warning(capsys, tmp_path):
    # A farm hands out fixed-size chunks: the last one runs past the end, as in Scene.frames
    # (a slice). It was refused on the command line and by inkwarp.render.
    import inkwarp

    scene = write_scene(tmp_path / "s")
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "frames/", "--frames", "2:16", "-q")
    assert code == 0 and stderr == ("inkwarp render: warning: --frames 2:16 runs past the scene's last frame (3); "
                                    "rendering 2:4\n"), stderr
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == ["frame_0002.png", "frame_0003.png"]
    written = inkwarp.render(inkwarp.Scene.load(scene), tmp_path / "py/", frames=(2, 16), progress=False)
    assert [p.name for p in written] == ["frame_0002.png", "frame_0003.png"]
    # A chunk wholly past the end renders nothing into a folder and succeeds (a farm's list
    # of fixed-size chunks overshot: no failed job); a video of no frames stays refused.
    for spec in ("4:8", "6:"):
        code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "frames/", "--frames", spec, "--skip-existing")
        assert code == 0 and stderr == (f"inkwarp render: warning: --frames {spec} starts past the scene's last frame (3): "
                                        "no frame to render\n"), stderr
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == ["frame_0002.png", "frame_0003.png"]
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "late.gif", "--frames", "4:8")
    assert code == 2 and "is not a range of the scene, which has frames 0 to 3" in stderr, stderr
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "frames/", "--frames", "50")  # no range at all
    assert code == 2 and "write a range A:B" in stderr, stderr
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "none/", "--frames", "8:4")
    assert code == 2 and "is not a range of the scene" in stderr and not (tmp_path / "none").exists(), stderr


def test_one_png_frame_with_ray_renders_here_with_a_note(capsys, tmp_path):
    # A farm's job template may pass --ray to every render: one frame was refused (exit 2).
    scene = write_scene(tmp_path / "s")
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "one.png", "--frame", "2", "--ray")
    assert code == 0 and stderr == ("inkwarp render: note: --ray renders animations; one .png frame renders on this "
                                    "machine\n"), stderr
    assert (tmp_path / "one.png").exists()


def test_a_background_of_three_numbers_says_what_to_write(capsys, tmp_path):
    scene = write_scene(tmp_path / "s", mutated(_set(["background"], [0, 0, 0])))
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "x.png")
    assert code == 2 and "background: expected exactly 4 items [R, G, B, A], each 0 to 255, found 3" in stderr, stderr


def test_a_time_past_the_end_renders_with_a_warning(capsys, tmp_path):
    # --frame past the end is refused; --time past it is a pose (the keys held), said so.
    scene = write_scene(tmp_path / "s")
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "x.png", "--time", "99")
    assert code == 0 and "warning: --time 99 is past the scene's end" in stderr, stderr
    assert (tmp_path / "x.png").exists()
    code, _, stderr = run(capsys, "field", scene, "-o", tmp_path / "x.npy", "--time", "99")
    assert code == 0 and "inkwarp field: warning: --time 99 is past the scene's end" in stderr, stderr
    assert (tmp_path / "x.npy").exists()
    code, _, stderr = run(capsys, "compare", scene, "-o", tmp_path / "c.png", "--time", "99", "--methods", "tps")
    assert code == 0 and "inkwarp compare: warning: --time 99 is past the scene's end" in stderr, stderr
    assert (tmp_path / "c.png").exists()
    # Said once: the API's own PastEndWarning is not given again beside the command's line.
    for command, out in (("render", "y.png"), ("field", "y.npy"), ("compare", "d.png")):
        code, _, stderr = run(capsys, command, scene, "-o", tmp_path / out, "--time", "99")
        assert code == 0 and stderr.count("past the scene's end") == 1 and "PastEndWarning" not in stderr, stderr


def test_a_time_before_zero_and_every_key_renders_with_a_warning(capsys, tmp_path):
    # A sign slipped on a farm (--time -1 for 1) gave the first keys' poses with no word.
    scene = write_scene(tmp_path / "s")
    for command, out, shows in (("render", "x.png", "the frame shows"), ("field", "x.npy", "the field is"),
                                ("compare", "c.png", "the sheet shows")):
        code, _, stderr = run(capsys, command, scene, "-o", tmp_path / out, "--time", "-1")
        assert code == 0 and (tmp_path / out).exists(), stderr
        assert stderr.count(f"inkwarp {command}: warning: --time -1 is before the scene's start (0 s); {shows} "
                            "the poses held before the first keys") == 1, stderr
        assert "PastEndWarning" not in stderr, stderr
    from inkwarp import PastEndWarning, Scene

    with pytest.warns(PastEndWarning, match="before the scene's start"):
        Scene.load(scene).render(time=-0.25)


def test_a_sprite_sheet_into_a_folder_named_like_a_png_says_it_is_a_folder(capsys, tmp_path):
    scene = write_scene(tmp_path / "s")
    (tmp_path / "adir.png").mkdir()
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "adir.png", "--sprite-sheet")
    assert code == 2 and "adir.png: is a folder" in stderr and "adir.png/sheet.png" in stderr, stderr
    assert list((tmp_path / "adir.png").iterdir()) == []


def test_frames_into_a_file_or_a_locked_folder_say_the_fix(capsys, tmp_path, monkeypatch):
    scene = write_scene(tmp_path / "s")
    (tmp_path / "afile").write_text("x")
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "afile")
    assert code == 2 and "is a file, not a directory for PNG frames; name a new folder" in stderr, stderr
    assert (tmp_path / "afile").read_text() == "x"
    # A folder this user may not write in (as root writes anywhere, the check is told so).
    from inkwarp import video

    locked = tmp_path / "locked"
    locked.mkdir()
    monkeypatch.setattr(video.os, "access", lambda path, mode: Path(path) != locked)
    for out in (locked, locked / "new/", locked / "x.gif"):
        code, _, stderr = run(capsys, "render", scene, "-o", out)
        assert code == 2 and "is not writable; choose a writable folder or change its permissions" in stderr, stderr


def test_one_frame_to_a_folder_named_like_a_png_says_it_is_a_folder(capsys, tmp_path):
    # An existing folder is where a sequence's frames go, whatever its name: one frame to
    # `isdir.png/` is refused for being a folder, not for not being named .png.
    scene = write_scene(tmp_path / "s")
    (tmp_path / "isdir.png").mkdir()
    for option, value in (("--frame", "1"), ("--time", "0.5")):
        code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "isdir.png", option, value)
        assert code == 2 and len(stderr.splitlines()) == 1, stderr
        assert "isdir.png: is a folder" in stderr and f"{option} writes one .png file" in stderr, stderr
    assert list((tmp_path / "isdir.png").iterdir()) == []
    # A folder that is not there yet (a trailing separator) is not called one that is.
    code, _, stderr = run(capsys, "render", scene, "-o", f"{tmp_path / 'new.png'}/", "--frame", "1")
    assert code == 2 and "is a folder" not in stderr and "--frame picks one frame" in stderr, stderr
    assert not (tmp_path / "new.png").exists()


def test_a_time_before_zero_renders_the_drawing_before_the_first_frame(capsys, tmp_path):
    # Keys may lie before 0 s; `render` and `field` take such a time as the Python API
    # and `compare` do (they refused it), and give what `Scene.render` / `Scene.field` give.
    from _cli_scenes import SHIFT_PX, dark_columns

    from inkwarp import Scene

    def early(doc):
        keys = doc["features"][0]["keys"]
        keys.insert(0, {"t": -1.0, "points": [[keys[0]["points"][0][0] - SHIFT_PX, keys[0]["points"][0][1]]],
                        "interpolation": "linear"})

    scene = write_scene(tmp_path / "s", mutated(early))
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "x.png", "--time", "-0.5")
    assert code == 0 and stderr == "", stderr
    frame = np.asarray(Image.open(tmp_path / "x.png").convert("RGBA"))
    want = Scene.load(scene).render(time=-0.5)
    assert np.array_equal(frame, want)
    at_zero = Scene.load(scene).render(time=0.0)
    assert dark_columns(frame)[0] < dark_columns(at_zero)[0] - 0.25 * SHIFT_PX  # moved left of its 0 s place
    code, _, stderr = run(capsys, "field", scene, "-o", tmp_path / "x.npy", "--time", "-5e-1")  # an exponent too
    assert code == 0 and stderr == "", stderr
    assert np.array_equal(np.load(tmp_path / "x.npy"), Scene.load(scene).field(time=-0.5))


def test_field_errors(capsys, tmp_path):
    scene = write_scene(tmp_path / "s")
    code, _, stderr = run(capsys, "field", scene, "--time", "1", "-o", tmp_path / "f.txt")
    assert code == 2 and "name the output .npy" in stderr
    # Past the times a scene holds: refused (it gave a field, with no word, at 1e300 s).
    code, _, stderr = run(capsys, "field", scene, "--time", "1e300", "-o", tmp_path / "f.npy")
    assert code == 2 and "--time 1e+300: give a time in seconds from -100000 to 100000" in stderr, stderr
    assert not (tmp_path / "f.npy").exists()
    code, _, stderr = run(capsys, "field", scene, "--time", "1", "--layer", "nope",
                          "-o", tmp_path / "f.npy")
    assert code == 2 and "nope" in stderr and len(stderr.splitlines()) == 1
    assert not (tmp_path / "f.npy").exists() and leftovers(tmp_path) == []
    # Two layers and no --layer: the file, the layers and the option to use.
    two = write_scene(tmp_path / "two", mutated(lambda d: d["layers"].append({**d["layers"][0], "name": "top"})))
    code, _, stderr = run(capsys, "field", two, "--time", "1", "-o", tmp_path / "f.npy")
    assert code == 2 and len(stderr.splitlines()) == 1, stderr
    assert str(two) in stderr and "2 layers" in stderr and "--layer NAME" in stderr and "layer=" not in stderr
    assert not (tmp_path / "f.npy").exists()


def test_compare_names_its_own_options_in_errors(capsys, tmp_path):
    # Weights out of range blamed the scene's solver.beier_neely.a, and an unknown layer
    # named no file.
    scene = write_scene(tmp_path / "s")
    code, _, stderr = run(capsys, "compare", scene, "--beier-neely", "a=0", "-o", tmp_path / "c.png")
    assert code == 2 and "--beier-neely a=0: Beier–Neely's a must be" in stderr and "solver." not in stderr, stderr
    code, _, stderr = run(capsys, "compare", scene, "--layer", "fac", "-o", tmp_path / "c.png")
    assert code == 2 and f"{scene}: --layer fac: no layer is called that; the layers are square" in stderr, stderr
    assert not (tmp_path / "c.png").exists() and leftovers(tmp_path) == []


class _Breaks:
    """A scene whose frames fail (with ``error``) after ``good`` frames."""

    def __init__(self, real, error, good=2):
        self._real, self._error, self._good = real, error, good

    def __getattr__(self, name):
        return getattr(self._real, name)

    def frames(self, start=0, stop=None, **options):
        for i, frame in enumerate(self._real.frames(start=start, stop=stop, **options)):
            if i == self._good:
                raise self._error
            yield frame


@pytest.mark.parametrize("skip", [False, True])
def test_an_interrupt_while_a_frame_is_written_ends_with_the_word(capsys, tmp_path, monkeypatch, skip):
    # The progress display of frames cut short was closed by the garbage collector, after
    # the command had said "interrupted": its last line came after that word.
    from inkwarp import rendering, video

    scene = write_scene(tmp_path / "s")
    calls = []

    def third_interrupted(write):
        def counted(*args):
            calls.append(1)
            if len(calls) == 3:
                raise KeyboardInterrupt
            return write(*args)
        return counted

    if skip:  # (frames written one by one: `_write_new_frame`)
        monkeypatch.setattr(rendering, "_write_new_frame", third_interrupted(rendering._write_new_frame))
    else:
        monkeypatch.setattr(video.PngSequenceWriter, "write", third_interrupted(video.PngSequenceWriter.write))
    code, _, stderr = run(capsys, "render", scene, "-o", tmp_path / "frames/", *(["--skip-existing"] if skip else []))
    assert code == 130 and stderr.endswith("inkwarp render: interrupted\n") and "(2/" in stderr, stderr


@pytest.mark.parametrize("output", ["anim.gif", "anim.mp4", "frames", "frames/"])
@pytest.mark.parametrize("error, code", [(RuntimeError("boom"), 1), (KeyboardInterrupt(), 130),
                                         (ValueError("the solve failed"), 2),
                                         # Python's own words for a program's mistake: a bug, not bad input.
                                         (ValueError("not enough values to unpack (expected 4, got 3)"), 1)])
def test_a_failed_render_leaves_nothing_behind(capsys, tmp_path, monkeypatch, output, error,
                                               code):
    import inkwarp

    scene = write_scene(tmp_path / "s")
    real_load = inkwarp.Scene.load
    monkeypatch.setattr(inkwarp.Scene, "load",
                        staticmethod(lambda path: _Breaks(real_load(path), error)))
    before = sorted(os.listdir(tmp_path))
    got, stdout, stderr = run(capsys, "render", scene, "-o", tmp_path / output)
    assert got == code
    assert sorted(os.listdir(tmp_path)) == before
    if code == 1:
        assert "internal error" in stderr and "Traceback" in stderr
    else:
        assert "Traceback" not in stderr
        last = stderr.rstrip("\n").split("\n")[-1]  # after the progress bar's line
        assert last in ("inkwarp render: interrupted", "inkwarp render: error: the solve failed")


def test_a_failed_render_keeps_the_previous_output(capsys, tmp_path, monkeypatch):
    import inkwarp

    scene = write_scene(tmp_path / "s")
    out = tmp_path / "anim.gif"
    assert run(capsys, "render", scene, "-o", out, "-q")[0] == 0
    previous = out.read_bytes()
    real_load = inkwarp.Scene.load
    monkeypatch.setattr(inkwarp.Scene, "load",
                        staticmethod(lambda path: _Breaks(real_load(path), RuntimeError("x"))))
    assert run(capsys, "render", scene, "-o", out)[0] == 1
    assert out.read_bytes() == previous and leftovers(tmp_path) == []


def test_the_installed_command_exits_2_without_a_traceback(tmp_path):
    scene = write_scene(tmp_path, mutated(_set(["fps"], 0)))
    done = subprocess.run([sys.executable, "-m", "inkwarp.cli", "render", str(scene), "-o",
                           str(tmp_path / "x.mp4")], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.startswith(f"inkwarp render: error: {scene}: fps: ")
    assert len(done.stderr.splitlines()) == 1 and done.stdout == ""
    script = Path(sys.executable).with_name("inkwarp")
    if script.exists():
        done = subprocess.run([str(script), "validate", str(scene)], capture_output=True,
                              text=True)
        assert done.returncode == 2 and f"{scene}: fps: " in done.stdout


def test_ctrl_c_while_the_command_starts_exits_130_without_a_traceback(tmp_path):
    # Ctrl+C within the few tenths of a second of the command's imports printed numpy's
    # traceback. As the `inkwarp` command (argv[0]), a SIGINT right after `import inkwarp`,
    # before `main` runs, ends it with one line; once `main` runs, Ctrl+C is the command's
    # own again (a render says "interrupted", tested above), and a program of another name
    # keeps Python's KeyboardInterrupt.
    start = ("import os, signal, sys, time; sys.argv[0] = {name!r}; import inkwarp{then}; "
             "os.kill(os.getpid(), signal.SIGINT); time.sleep(5); print('not interrupted')")

    def run_as(name, then=""):
        # SIGINT as a terminal gives it (a test run in the background may have it ignored).
        return subprocess.run([sys.executable, "-c", start.format(name=name, then=then)], capture_output=True,
                              text=True, timeout=60, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))

    done = run_as("/usr/bin/inkwarp")
    assert (done.returncode, done.stderr, done.stdout) == (130, "inkwarp: interrupted\n", "")
    done = run_as("inkwarp", "; from inkwarp.cli import main; main(['schema', '-o', {!r}])".format(str(tmp_path / "s.json")))
    assert done.returncode != 130 and "KeyboardInterrupt" in done.stderr, done.stderr
    done = run_as("my_tool.py")
    assert done.returncode != 130 and "KeyboardInterrupt" in done.stderr, done.stderr


def test_no_command_prints_help_and_exits_2(capsys):
    assert main([]) == 2
    assert "usage: inkwarp" in capsys.readouterr().err


def render_underway(tmp_path, duration, signum, action):
    """A render of the square scene lasting `duration` seconds (4 frames a second) into PNG
    frames, in a child process whose signal `signum` starts as `action` (a run may ignore
    SIGHUP, as under nohup, and its children with it), once its first temporary file is there."""
    import time

    from _cli_scenes import square_doc

    doc = square_doc()
    doc["duration"] = duration
    scene = write_scene(tmp_path / "s", doc)
    process = subprocess.Popen([sys.executable, "-m", "inkwarp.cli", "render", str(scene), "-o", str(tmp_path / "frames"),
                                "-q"], stderr=subprocess.PIPE, text=True, preexec_fn=lambda: signal.signal(signum, action))
    deadline = time.monotonic() + 120
    while not leftovers(tmp_path) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    return process


@pytest.mark.parametrize("name, said", [("SIGTERM", "terminated"), ("SIGHUP", "hung up")])
def test_sigterm_mid_render_leaves_nothing_behind(tmp_path, name, said):
    # SIGHUP: the terminal closed or the SSH session was lost. Its default action killed the
    # render with its temporary file left beside the output.
    import time

    number = getattr(signal, name, None)
    if number is None:
        pytest.skip(f"no {name} here")
    # 2000 frames: far more than the time it takes to stop it.
    process = render_underway(tmp_path, 500.0, number, signal.SIG_DFL)
    time.sleep(0.2)  # a few frames in
    process.send_signal(number)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 128 + number, stderr
    assert stderr.strip().endswith(f"inkwarp render: {said}")
    assert sorted(os.listdir(tmp_path)) == ["s"]


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="no SIGHUP here")
def test_a_render_under_nohup_goes_on_when_its_terminal_closes(tmp_path):
    # nohup starts it with SIGHUP ignored: the render must not take it back.
    import time

    # 20,000 frames: running still when it is looked at.
    process = render_underway(tmp_path, 5000.0, signal.SIGHUP, signal.SIG_IGN)
    process.send_signal(signal.SIGHUP)
    time.sleep(0.5)
    assert process.poll() is None, process.communicate()
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 128 + signal.SIGTERM and sorted(os.listdir(tmp_path)) == ["s"], stderr


@pytest.mark.parametrize("command", [["render", "{scene}"], ["new", "{picture}"], ["field", "{scene}", "--time", "1"]])
def test_an_empty_output_is_refused_not_taken_for_here(capsys, tmp_path, monkeypatch, command):
    # -o "$OUT" with OUT unset: nothing is written into the working directory.
    scene = write_scene(tmp_path / "s")
    monkeypatch.chdir(tmp_path / "s")
    before = sorted(p.name for p in (tmp_path / "s").iterdir())
    argv = [a.format(scene=scene, picture=tmp_path / "s" / "square.png") for a in command]
    code, _, err = run(capsys, *argv, "-o", "")
    assert code == 2 and "-o is empty" in err and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in (tmp_path / "s").iterdir()) == before


def test_every_command_refuses_a_missing_folder_or_a_folder_for_its_output_file(capsys, tmp_path):
    # compare and transfer made missing folders (a typo became a new folder), and a folder
    # given as the output file was named by its temporary file, or was an internal error.
    scene = write_scene(tmp_path / "s")
    other = write_scene(tmp_path / "s", name="other.json")
    for name in ("d.png", "d.npy", "d.json"):
        (tmp_path / name).mkdir()
    missing = tmp_path / "typo"
    for args, says in [
        (["compare", scene, "--methods", "tps", "-o", missing / "a.png"], f"the directory {missing} does not exist; create it first"),
        (["transfer", "--source", scene, "--target", other, "-o", missing / "a.json"], f"the directory {missing} does not exist"),
        (["compare", scene, "--methods", "tps", "-o", tmp_path / "d.png"], "d.png: is a directory; name a file"),
        (["field", scene, "--time", "0.5", "-o", tmp_path / "d.npy"], "d.npy: is a directory; name a file"),
        (["transfer", "--source", scene, "--target", other, "-o", tmp_path / "d.json"], "d.json: is a directory; name a file"),
        (["schema", "-o", tmp_path / "d.json"], "d.json: is a directory; name a file"),
        (["schema", "-o", tmp_path], "is a directory; name a file, such as"),
    ]:
        code, _, stderr = run(capsys, *args)
        assert code == 2 and says in stderr and ".part" not in stderr and len(stderr.splitlines()) == 1, (args, stderr)
    assert not missing.exists()


def test_no_command_replaces_the_users_own_files(capsys, tmp_path):
    # field and compare over a scene's picture, transfer over its source or target, a
    # sprite sheet's atlas over another scene or an unrelated JSON, and the schema over a
    # scene all wrote over them with exit status 0.
    scene = write_scene(tmp_path)
    other = write_scene(tmp_path, name="other.json")
    (tmp_path / "notes.json").write_text('{"hello": 1}\n')
    files = {p: p.read_bytes() for p in (tmp_path / "square.png", scene, other, tmp_path / "notes.json")}
    for args, says in [
        (["field", scene, "--time", "0.5", "-o", tmp_path / "square.png"], "writing the field there would replace it"),
        (["compare", scene, "--methods", "tps", "-o", tmp_path / "square.png"], "writing the comparison sheet there"),
        (["transfer", "--source", scene, "--target", other, "-o", other], "is the input (--target"),
        (["transfer", "--source", scene, "--target", other, "-o", scene], "is the input (--source"),
        (["render", scene, "-o", tmp_path / "other.png", "--sprite-sheet"], "the sprite sheet's other.json is a scene"),
        (["render", scene, "-o", tmp_path / "notes.png", "--sprite-sheet"], "notes.json is a file inkwarp did not write"),
        (["schema", "-o", other], "other.json: is a scene; writing the schema there would replace it"),
        (["schema", "-o", tmp_path / "notes.json"], "notes.json: is a file inkwarp did not write"),
    ]:
        code, _, stderr = run(capsys, *args)
        assert code == 2 and says in stderr and len(stderr.splitlines()) == 1, (args, stderr)
    # Another tool's JSON schema is not an earlier schema of inkwarp's.
    (tmp_path / "biome.json").write_text('{"$schema": "https://biomejs.dev/schemas/1.9.4/schema.json"}\n')
    code, _, stderr = run(capsys, "schema", "-o", tmp_path / "biome.json")
    assert code == 2 and "biome.json: is a file inkwarp did not write" in stderr, stderr
    # A loaded Scene rendered as a sprite sheet by Python: the same checks.
    import inkwarp

    for name, says in (("scene.png", "would replace the scene"), ("other.png", "other.json is a scene")):
        with pytest.raises(ValueError, match=says):
            inkwarp.render(inkwarp.Scene.load(scene), tmp_path / name, sprite_sheet=True)
    assert {p: p.read_bytes() for p in files} == files
    assert not (tmp_path / "other.png").exists() and not (tmp_path / "notes.png").exists()
    # Their own earlier outputs are replaced as before.
    for args in (["schema", "-o", tmp_path / "s.json"], ["render", scene, "-o", tmp_path / "sheet.png", "--sprite-sheet"],
                 ["transfer", "--source", scene, "--target", other, "-o", tmp_path / "t.json"]):
        assert run(capsys, *args)[0] == 0 and run(capsys, *args)[0] == 0, args
