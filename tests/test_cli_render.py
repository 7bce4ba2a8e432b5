"""`inkwarp render` and `inkwarp field` on a small real scene: every output kind read back."""

from __future__ import annotations

import json
from pathlib import Path
import re

import numpy as np
import pytest
from PIL import Image

from _cli_scenes import (FPS, HEIGHT, SHIFT_PX, WIDTH, dark_columns, leftovers, read_mp4,
                         square_centroid_at, write_scene)
from inkwarp.cli import main

FRAMES = 4  # ceil(DURATION * FPS)


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def scene(tmp_path):
    return write_scene(tmp_path / "scene")


def read_png(path):
    return np.asarray(Image.open(path).convert("RGBA"))


def assert_square_at(frame, index, tol=0.01):
    x, y = dark_columns(frame)
    ex, ey = square_centroid_at(index)
    assert abs(x - ex) <= tol and abs(y - ey) <= tol, (index, (x, y), (ex, ey))


def test_png_at_a_time_shows_the_square_moved(capsys, scene, tmp_path):
    out = tmp_path / "still.png"
    code, stdout, _ = run(capsys, "render", scene, "-o", out, "--time", 0.5)
    assert code == 0
    frame = read_png(out)
    assert frame.shape == (HEIGHT, WIDTH, 4)
    assert_square_at(frame, 2)  # t = 0.5 s is frame 2 at 4 fps
    assert str(out) in stdout


def test_png_of_a_frame_and_the_default_frame_zero(capsys, scene, tmp_path):
    code, _, _ = run(capsys, "render", scene, "-o", tmp_path / "f3.png", "--frame", 3)
    assert code == 0
    assert_square_at(read_png(tmp_path / "f3.png"), 3)
    code, _, _ = run(capsys, "render", scene, "-o", tmp_path / "f0.png", "-q")
    assert code == 0
    frame0 = read_png(tmp_path / "f0.png")
    assert_square_at(frame0, 0)
    # At rest the layer comes back exactly: the square's pixels are the picture's.
    assert (frame0[14:22, 10:18, :3] == (20, 30, 200)).all()


def test_directory_holds_every_frame_in_order(capsys, scene, tmp_path):
    out = tmp_path / "frames"
    code, _, err = run(capsys, "render", scene, "-o", f"{out}/")
    assert code == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [f"frame_{i:04d}.png" for i in range(FRAMES)]
    for i, name in enumerate(names):
        assert_square_at(read_png(out / name), i)
    assert "frames" in err  # the progress bar, on stderr
    assert leftovers(tmp_path) == []


def test_directory_ranges_land_under_their_frame_numbers(capsys, scene, tmp_path):
    out = tmp_path / "frames"
    assert run(capsys, "render", scene, "-o", out, "--frames", "2:4", "-q")[0] == 0
    assert sorted(p.name for p in out.iterdir()) == ["frame_0002.png", "frame_0003.png"]
    (out / "notes.txt").write_text("mine")
    assert run(capsys, "render", scene, "-o", out, "--frames", ":2", "-q")[0] == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [f"frame_{i:04d}.png" for i in range(FRAMES)] + ["notes.txt"]
    for i in range(FRAMES):
        assert_square_at(read_png(out / f"frame_{i:04d}.png"), i)
    assert (out / "notes.txt").read_text() == "mine"


def test_a_directory_whose_name_has_a_dot_is_one_when_it_ends_in_a_slash(capsys, scene, tmp_path):
    import inkwarp

    code, _, err = run(capsys, "render", scene, "-o", f"{tmp_path / 'shot010_v1.2'}/", "--frames", "0:2", "-q")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "shot010_v1.2").iterdir()) == ["frame_0000.png", "frame_0001.png"]
    paths = inkwarp.render(str(scene), f"{tmp_path / 'take_v2.0'}/", frames=(1, 3))
    assert [p.name for p in paths] == ["frame_0001.png", "frame_0002.png"]
    assert (tmp_path / "take_v2.0").is_dir() and leftovers(tmp_path) == []
    # Without the slash the suffix is a format, and the message says how to name a folder.
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "shot_v1.3", "-q")
    assert code == 2 and "cannot write '.2' files" not in err
    assert "cannot write '.3' files" in err and "end the name with /" in err
    assert not (tmp_path / "shot_v1.3").exists()


def test_gif_has_every_frame_at_the_scene_rate(capsys, scene, tmp_path):
    out = tmp_path / "anim.gif"
    code, stdout, _ = run(capsys, "render", scene, "-o", out)
    assert code == 0
    with Image.open(out) as gif:
        assert gif.size == (WIDTH, HEIGHT)
        assert gif.n_frames == FRAMES
        total_ms = 0
        for i in range(FRAMES):
            gif.seek(i)
            total_ms += gif.info["duration"]
            assert_square_at(np.asarray(gif.convert("RGB")), i, tol=0.05)
    assert total_ms == 1000 * FRAMES // FPS
    assert f"{FRAMES} frames" in stdout


@pytest.mark.parametrize("fps, background", [(60, None), (240, None), (60, [0, 0, 0, 0])])
def test_a_gif_above_50_fps_leaves_frames_out_and_keeps_its_length(capsys, tmp_path, fps, background):
    # Browsers play a GIF delay of 1/100 s or less as 1/10 s: 60 fps wrote 10 and 20 ms
    # delays (a clip several times slower there), 240 fps 10 ms each (2.4 s for 1 s).
    # Opaque and transparent scenes take the two GIF writers.
    doc = json.loads(write_scene(tmp_path / "s").read_text())
    doc.update(fps=fps, duration=1.0, **({"background": background} if background else {}))
    scene = write_scene(tmp_path / "s", doc)
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif", "-q")
    assert code == 0 and f"of its {fps} frames left out, as browsers play a GIF at most 50" in err, err
    # Through Python, the warning names the caller's line, not inkwarp's.
    import inkwarp

    with pytest.warns(inkwarp.InkwarpWarning, match="frames left out") as caught:
        inkwarp.render(inkwarp.Scene.load(scene), tmp_path / "b.gif")
    assert caught[0].filename == __file__, caught[0].filename
    with Image.open(tmp_path / "a.gif") as gif:
        delays = []
        for i in range(gif.n_frames):
            gif.seek(i)
            delays.append(gif.info["duration"])
    assert min(delays) >= 20 and sum(delays) == 1000, delays
    if background is None:
        assert len(delays) == 50


def test_frames_range_renders_only_those_frames(capsys, scene, tmp_path):
    out = tmp_path / "part.gif"
    assert run(capsys, "render", scene, "-o", out, "--frames", "2:", "-q")[0] == 0
    with Image.open(out) as gif:
        assert gif.n_frames == FRAMES - 2
        assert_square_at(np.asarray(gif.convert("RGB")), 2, tol=0.05)


def test_mp4_is_h264_with_every_frame(capsys, scene, tmp_path):
    out = tmp_path / "anim.mp4"
    code, _, _ = run(capsys, "render", scene, "-o", out)
    assert code == 0
    frames, info = read_mp4(out, WIDTH, HEIGHT)
    assert re.search(rf"Video: h264 .*yuv420p.*, {WIDTH}x{HEIGHT}\b", info), info
    assert re.search(rf"\b{FPS} fps\b", info), info
    assert len(frames) == FRAMES
    for i, frame in enumerate(frames):
        assert_square_at(frame, i, tol=0.35)  # lossy, chroma-subsampled
    assert leftovers(tmp_path) == []


def test_odd_sizes_make_an_even_mp4(capsys, tmp_path):
    from _cli_scenes import square_doc

    doc = square_doc()
    doc["width"], doc["height"] = 47, 39
    scene = tmp_path / "odd" / "scene.json"
    write_scene(scene.parent, doc)
    Image.fromarray(np.asarray(Image.open(scene.parent / "square.png"))[:39, :47]).save(
        scene.parent / "square.png")
    out = tmp_path / "odd.mp4"
    code, said, _ = run(capsys, "render", scene, "-o", out)
    assert code == 0 and "47x39 padded to 48x40" in said, said  # the summary said 47x39 of a 48x40 file
    frames, info = read_mp4(out, 48, 40)
    assert ", 48x40" in info and len(frames) == 4


def test_field_npy_is_the_translation(capsys, scene, tmp_path):
    out = tmp_path / "field.npy"
    code, stdout, _ = run(capsys, "field", scene, "--time", 0.5, "-o", out)
    assert code == 0
    field = np.load(out)
    assert field.dtype == np.float32 and field.shape == (HEIGHT, WIDTH, 2)
    square = field[14:22, 10:18]
    assert np.allclose(square[..., 0], SHIFT_PX / 2, atol=0.01)
    assert np.allclose(square[..., 1], 0.0, atol=0.01)
    assert "largest move 4.00 px" in stdout


def test_field_of_a_layer_by_frame_and_as_a_picture(capsys, scene, tmp_path):
    npy = tmp_path / "f.npy"
    assert run(capsys, "field", scene, "--frame", 1, "--layer", "square", "-o", npy, "-q")[0] == 0
    assert np.allclose(np.load(npy)[14:22, 10:18, 0], SHIFT_PX / 4, atol=0.01)
    png = tmp_path / "f.png"
    assert run(capsys, "field", scene, "--time", 1, "-o", png, "-q")[0] == 0
    picture = read_png(png)
    assert picture.shape == (HEIGHT, WIDTH, 4)
    r, g, b, _ = picture[17, 13].astype(int)  # moving right at full length: red
    assert r == 255 and g < 60 and b < 60


def test_validate_ok_prints_the_summary(capsys, scene):
    code, stdout, _ = run(capsys, "validate", scene)
    assert code == 0
    assert stdout.startswith(f"ok: {scene}: ")
    for part in ("48x40", "1 layer (square)", "1 feature (1 point)", "4 frames at 4 fps",
                 "(1 s)"):
        assert part in stdout
    assert "note:" not in stdout


def test_validate_notes_what_is_allowed_but_probably_a_mistake(capsys, tmp_path):
    # A feature typed off the picture, a key after the end and a feature no layer lists
    # all render; validate names each after its "ok" (and still exits 0), and render the key
    # after the end, which cuts its animation short.
    path = write_scene(tmp_path / "scene")
    doc = json.loads(path.read_text())
    point = doc["features"][0]
    doc["features"] += [
        {"id": "typo", "kind": "point", "rest": [[470, 20]], "keys": [{"t": 0.5, "points": [[475, 20]]}]},
        {"id": "late", "kind": "point", "rest": point["rest"], "keys": [{"t": 3.0, "points": point["rest"]}]},
        {"id": "spare", "kind": "cut", "rest": [[0, 30], [20, 30]]},
        # Points off the picture, but the line through them touches its edge.
        {"id": "dips", "kind": "cut", "rest": [[-6, 10], [0, 20], [-6, 30]]},
        # Straight segments stay within their vertices' box (a spline's box is widened).
        {"id": "beyond", "kind": "polyline", "rest": [[WIDTH + 3, 5], [WIDTH + 40, 20]]},
    ]
    doc["layers"][0]["features"] = [point["id"], "typo", "late", "dips", "beyond"]
    path.write_text(json.dumps(doc))
    code, stdout, _ = run(capsys, "validate", path)
    assert code == 0
    ok, *notes = stdout.splitlines()
    assert ok.startswith(f"ok: {path}: ")
    assert notes == [
        f"note: {path}: features[1]: 'typo' lies wholly off the picture, so it moves nothing: its rest points span "
        f"x 470 to 470, y 20 to 20, the picture's pixel centres x 0 to {WIDTH - 1}, y 0 to {HEIGHT - 1}",
        f"note: {path}: features[2].keys[0].t: 'late' has a key at 3 s, after the scene's end (1 s): no frame shows "
        "it, the frames before it show the move toward it; a duration of 3.25 s ends on it, or move the key",
        f"note: {path}: features[3]: 'spare' drives no layer: every layer lists its features and none lists it; "
        "add it to a layer's features",
        f"note: {path}: features[5]: 'beyond' lies wholly off the picture, so it moves nothing: its rest points span "
        f"x {WIDTH + 3} to {WIDTH + 40}, y 5 to 20, the picture's pixel centres x 0 to {WIDTH - 1}, y 0 to {HEIGHT - 1}",
    ]
    import inkwarp

    assert [p for p, _ in inkwarp.Scene.load(path).notes()] == ["features[1]", "features[2].keys[0].t", "features[3]",
                                                               "features[5]"]
    code, _, err = run(capsys, "render", path, "-o", tmp_path / "a.gif")
    assert code == 0 and err.splitlines()[0] == "inkwarp render: " + notes[1], err
    assert "'typo'" not in err and "'spare'" not in err
    code, _, err = run(capsys, "render", path, "-o", tmp_path / "a.gif", "-q")
    assert code == 0 and err == ""


def test_validate_notes_keys_before_the_start_empty_layers_and_every_layer_hidden(capsys, tmp_path):
    # A key before 0 s with one after it leaves frame 0 part way between them; a shown
    # layer wholly transparent draws nothing; with every layer hidden each frame is the
    # background alone. Each renders, with a note; a key before 0 s that a key at 0 s
    # follows, and a hidden empty layer, get none. (`--time` before 0 s renders the
    # drawing then without a word, as keys before 0 s may be meant.)
    path = write_scene(tmp_path / "scene")
    doc = json.loads(path.read_text())
    grip = doc["features"][0]
    grip["keys"] = [{"t": -1.0, "points": grip["rest"]}, {"t": 0.5, "points": grip["rest"]}]
    doc["features"].append({"id": "held", "kind": "point", "rest": grip["rest"],
                            "keys": [{"t": -1.0, "points": grip["rest"]}, {"t": 0.0, "points": grip["rest"]}]})
    Image.new("RGBA", (WIDTH, HEIGHT)).save(tmp_path / "scene" / "empty.png")
    doc["layers"] += [{"name": "blank", "image": "empty.png"}, {"name": "off", "image": "empty.png", "visible": False}]
    path.write_text(json.dumps(doc))
    code, stdout, _ = run(capsys, "validate", path)
    assert code == 0
    assert stdout.splitlines()[1:] == [
        f"note: {path}: features[0].keys[0].t: 'grip' has a key at -1 s, before the scene's start (0 s): no frame "
        "shows it, and frame 0 is already part way to the key at 0.5 s; unless that is meant, move the key to 0 s",
        f"note: {path}: layers[1]: layer 'blank' has no opaque pixel (its picture is wholly transparent): it shows "
        "nothing; give it a picture with opaque pixels, or remove it",
    ]
    # A key that holds its pose until the next is what frame 0 shows; an opaque picture
    # with an empty continuity matte shows, unmoved.
    import inkwarp

    grip["keys"][0]["interpolation"] = "hold"
    doc["layers"][1] = {"name": "still", "image": "square.png", "continuity": "empty.png"}
    path.write_text(json.dumps(doc))
    assert inkwarp.Scene.load(path).notes() == [
        ("layers[1]", "layer 'still''s continuity matte has no nonzero pixel: its picture shows, but nothing moves it; "
         "give the matte nonzero pixels where the picture should move, or drop \"continuity\"")]
    for layer in doc["layers"]:
        layer["visible"] = False
    path.write_text(json.dumps(doc))
    assert ("layers", "every layer is hidden (\"visible\": false), so every frame shows the background alone; set "
            "\"visible\": true on the layers to draw") in inkwarp.Scene.load(path).notes()


def test_a_key_far_off_the_picture_is_noted_and_its_stalled_solve_blames_it(capsys, tmp_path):
    # A key pasted from a tracing 20 times larger: validate said ok, a still frame rendered
    # smeared without a word. At a million pixels the solve stops at the field's precision,
    # and the warning advised a coarser tolerance (the default's) instead of naming the keys.
    path = write_scene(tmp_path / "scene")
    doc = json.loads(path.read_text())
    grip = doc["features"][0]
    grip["keys"] = [{"t": 0.0, "points": grip["rest"]}, {"t": 0.5, "points": [[x * 20, y * 20] for x, y in grip["rest"]]},
                    {"t": 0.75, "points": [[x * 30, y * 30] for x, y in grip["rest"]]}]
    path.write_text(json.dumps(doc))
    (x, y), = grip["rest"]
    note = (f"features[0].keys[1].points: 'grip' has a key at 0.5 s (and 1 more of its keys) whose points reach x {x * 20:g} "
            f"to {x * 20:g}, y {y * 20:g} to {y * 20:g}, further off the picture ({WIDTH} x {HEIGHT}) than its longer side: "
            "the surface is pulled that far, and the picture smears; were the points traced on a larger picture? scale "
            "them to this one")
    code, stdout, _ = run(capsys, "validate", path)
    assert code == 0 and stdout.splitlines()[1:] == [f"note: {path}: {note}"]
    code, _, err = run(capsys, "render", path, "--frame", "2", "-o", tmp_path / "f.png")
    assert code == 0 and err.splitlines()[0] == f"inkwarp render: note: {path}: {note}", err
    grip["keys"][1]["points"] = [[1e6, 1e6]]
    path.write_text(json.dumps(doc))
    code, _, err = run(capsys, "render", path, "--frame", "2", "-o", tmp_path / "f.png")
    assert code == 0 and "did not converge" in err and "too large for the field's precision (keys far off the picture?)" in err
    assert "coarser solver.tolerance" not in err, err


def test_validate_notes_lines_and_regions_with_no_extent(tmp_path):
    # A spline whose points coincide holds one pixel; a region whose points lie on one line
    # holds only its outline. Both validated without a word.
    import inkwarp

    Image.fromarray(np.full((HEIGHT, WIDTH, 4), 200, np.uint8)).save(tmp_path / "p.png")
    doc = {"inkwarp": 1, "layers": [{"name": "l", "image": "p.png"}], "features": [
        {"id": "dot", "kind": "spline", "rest": [[30, 30], [30, 30]]},
        {"id": "flat", "kind": "region", "rest": [[5, 5], [10, 10], [20, 20]]},
        {"id": "eight", "kind": "region", "rest": [[0, 0], [10, 10], [10, 0], [0, 10]]},
        {"id": "fine", "kind": "polyline", "rest": [[5, 5], [6, 5]]}]}
    notes = inkwarp.Scene.from_dict(doc, base_dir=tmp_path).notes()
    assert notes == [
        ("features[0].rest", "'dot', a spline, has all its points at one place (30, 30): it holds that one pixel, "
         "as a point does; spread its points along what it traces"),
        ("features[1].rest", "'flat', a region, has no area (its points lie on one line): it holds nothing inside, "
         "only its outline, as a polyline does; trace around what it should hold")], notes


def test_a_feature_beside_the_frame_over_a_layer_moved_there_is_no_slip(tmp_path):
    # A layer moved 20 px left of the frame: a pin traced at x = -10 holds its pixel 10
    # (off the frame, but on the layer, which the warp can pull into view); one at -30 is
    # off both.
    import inkwarp

    Image.fromarray(np.full((HEIGHT, WIDTH, 4), 200, np.uint8)).save(tmp_path / "p.png")
    doc = {"inkwarp": 1, "fps": 4, "duration": 1, "layers": [{"name": "l", "image": "p.png", "offset": [-20, 0]}],
           "features": [{"id": "pin", "kind": "point", "rest": [[-10, 5]]}, {"id": "far", "kind": "point", "rest": [[-30, 5]]}]}
    notes = inkwarp.Scene.from_dict(doc, base_dir=tmp_path).notes()
    assert [(path, message.split(" lies ")[0]) for path, message in notes] == [("features[1]", "'far'")], notes

def test_validate_notes_a_feature_drawn_wholly_on_holes(capsys, tmp_path):
    # A pin traced on a cut-out's transparent pixels (or in a hole of a continuity matte) is
    # dropped by the solver: it pins and moves nothing, without a word at render time. The
    # note is the solver's own rule (each sample's nearest node, at grid_step 1).
    cutout = np.zeros((HEIGHT, WIDTH, 4), np.uint8)
    cutout[10:30, 11:30] = (200, 60, 60, 255)
    cutout[7, 19] = (200, 60, 60, 255)  # one opaque pixel on a curve's bend
    Image.fromarray(cutout, "RGBA").save(tmp_path / "cutout.png")
    matte = np.full((HEIGHT, WIDTH), 255, np.uint8)
    matte[5:15, 35:45] = 0
    Image.fromarray(matte).save(tmp_path / "holes.png")
    point = lambda id, x, y: {"id": id, "kind": "point", "rest": [[x, y]], "keys": [{"t": 0.5, "points": [[x + 3, y]]}]}  # noqa: E731
    doc = {"inkwarp": 1, "fps": 4, "duration": 1, "layers": [
        {"name": "cutout", "image": "cutout.png", "features": ["beside", "on", "half", "across", "bend", "ring", "patch"]},
        {"name": "plate", "continuity": "holes.png", "features": ["in_hole", "ring"]}],
        "features": [
            point("beside", 30, 20),  # the first transparent column
            point("on", 29, 20),
            point("half", 10.5, 20),  # halves round up, to the first opaque column
            {"id": "across", "kind": "polyline", "rest": [[2, 2], [40, 38]]},  # its ends off the square
            # The straight lines between its points pass at y 6; the curve bends to 6.75, onto
            # the one opaque pixel.
            {"id": "bend", "kind": "spline", "rest": [[5, 0], [12, 6], [26, 6], [33, 0]]},
            point("in_hole", 40, 10),
            # On the cutout's transparent pixels all round, but on the plate's connected ones.
            {"id": "ring", "kind": "spline", "closed": True, "rest": [[4, 4], [40, 4], [40, 36], [4, 36]]},
            {"id": "patch", "kind": "region", "rest": [[33, 2], [46, 2], [46, 12], [33, 12]]}]}
    (tmp_path / "s.json").write_text(json.dumps(doc))
    code, stdout, _ = run(capsys, "validate", tmp_path / "s.json")
    assert code == 0
    drop = "so it pins and moves nothing; trace it on the picture itself"
    assert stdout.splitlines()[1:] == [
        f"note: {tmp_path / 's.json'}: features[0]: 'beside' lies wholly on the transparent pixels of layer 'cutout', {drop}",
        f"note: {tmp_path / 's.json'}: features[5]: 'in_hole' lies wholly on the holes of the continuity matte of layer "
        f"'plate', {drop}",
        f"note: {tmp_path / 's.json'}: features[7]: 'patch' lies wholly on the transparent pixels of layer 'cutout', {drop}",
    ]
    # What the notes say is what the solver does: alone, each noted feature moves nothing,
    # and each of the others moves its layer.
    import inkwarp

    for name, layer, moves in [("beside", 0, False), ("patch", 0, False), ("in_hole", 1, False), ("on", 0, True),
                               ("half", 0, True), ("across", 0, True), ("bend", 0, True)]:
        alone = json.loads(json.dumps(doc))
        alone["layers"][layer]["features"] = [name]
        for f in alone["features"]:
            f.setdefault("keys", [{"t": 0.5, "points": [[x + 3, y] for x, y in f["rest"]]}])
        field = inkwarp.Scene.from_dict(alone, base_dir=tmp_path).field(time=1.0, layer=layer)
        assert (np.abs(field).max() > 1) == moves, name
    # At grid_step 2 samples go to the coarse nodes: no note is given there. A layer with
    # an alpha matte but no image is solved on a whole grid: nothing is on a hole.
    doc["solver"] = {"grid_step": 2}
    doc["layers"][1] = {"name": "plate", "alpha": "holes.png", "features": ["in_hole", "ring"]}
    assert inkwarp.Scene.from_dict(doc, base_dir=tmp_path).notes() == []


def test_the_holes_note_is_judged_on_the_layers_drawn(tmp_path):
    # A pin on a cut-out's transparent pixels that also drives a hidden, opaque layer still
    # moves nothing that shows: the note is given. Shown, that layer takes the pin.
    cutout = np.zeros((HEIGHT, WIDTH, 4), np.uint8)
    cutout[10:30, 11:30] = (200, 60, 60, 255)
    Image.fromarray(cutout, "RGBA").save(tmp_path / "cutout.png")
    Image.fromarray(np.full((HEIGHT, WIDTH, 4), 255, np.uint8), "RGBA").save(tmp_path / "opaque.png")
    doc = {"inkwarp": 1, "fps": 4, "duration": 1, "layers": [
        {"name": "cutout", "image": "cutout.png"}, {"name": "sketch", "image": "opaque.png", "visible": False}],
        "features": [{"id": "beside", "kind": "point", "rest": [[30, 20]], "keys": [{"t": 0.5, "points": [[33, 20]]}]}]}
    notes = inkwarp_scene(doc, tmp_path).notes()
    assert [(path, message.split(", so it")[0]) for path, message in notes] == [
        ("features[0]", "'beside' lies wholly on the transparent pixels of layer 'cutout'")], notes
    doc["layers"][1]["visible"] = True
    assert inkwarp_scene(doc, tmp_path).notes() == []
    doc["layers"][0]["visible"] = doc["layers"][1]["visible"] = False  # none drawn: judged on all
    doc["layers"][1]["image"] = "cutout.png"
    assert [path for path, _ in inkwarp_scene(doc, tmp_path).notes()] == ["features[0]", "layers"]  # and all hidden


def test_validate_notes_a_matte_that_falls_apart_at_its_grid_step(tmp_path):
    # Hair 1 px wide on odd rows has no node on the coarse grid of grid_step 2, and a
    # diagonal strand no straight link between its nodes there: their pixels move with a
    # neighbouring part, unbent (on a tangle of hair, most of them over 1 px off the full
    # solve). The note counts the pieces on either grid; at grid_step 1, none.
    cutout = np.zeros((HEIGHT, WIDTH, 4), np.uint8)
    cutout[20:36, 4:16] = (200, 60, 60, 255)  # a head
    cutout[21, 16:46] = cutout[27, 16:46] = (90, 60, 30, 255)  # two straight hairs on odd rows
    for k in range(24):
        cutout[19 - k // 2 - k % 2, 10 + k // 2] = (90, 60, 30, 255)  # a diagonal hair, 4-connected
    Image.fromarray(cutout, "RGBA").save(tmp_path / "hair.png")
    doc = {"inkwarp": 1, "fps": 4, "duration": 1, "solver": {"grid_step": 2}, "layers": [{"name": "head", "image": "hair.png"}],
           "features": [{"id": "pin", "kind": "point", "rest": [[8, 28]], "keys": [{"t": 0.5, "points": [[9, 28]]}]}]}
    (note,) = inkwarp_scene(doc, tmp_path).notes()
    assert note[0] == "layers[0]", note
    assert note[1].startswith("at grid_step 2 the matte of layer 'head' falls into "), note
    pieces = re.match(r".* falls into (\d+) pieces on the coarse grid it is solved on, against (\d+) at full resolution", note[1])
    assert pieces and int(pieces[1]) > int(pieces[2]) == 1, note
    assert note[1].endswith("use grid_step 1 for this layer"), note
    doc["layers"][0]["solver"] = {"grid_step": 1}
    assert inkwarp_scene(doc, tmp_path).notes() == []
    # A solid cut-out at grid_step 2 (its antialiased rim included) keeps its one piece: no note.
    disc = np.zeros((HEIGHT, WIDTH, 4), np.uint8)
    yy, xx = np.mgrid[:HEIGHT, :WIDTH]
    disc[..., 3] = np.clip((15.5 - np.hypot(xx - 24, yy - 20)) * 255, 0, 255).astype(np.uint8)
    Image.fromarray(disc, "RGBA").save(tmp_path / "disc.png")
    doc["layers"] = [{"name": "disc", "image": "disc.png"}]
    assert inkwarp_scene(doc, tmp_path).notes() == []


def test_validate_notes_features_that_clash_on_the_coarse_grid_of_its_grid_step(tmp_path, capsys):
    # The face example's lips part: at grid_step 8 samples of both lips share coarse nodes,
    # and each node holds the nearest of them, so the mouth tore open with no note.
    face = Path(__file__).resolve().parents[1] / "examples" / "face"
    doc = json.loads((face / "scene.json").read_text())
    doc["solver"] = {**doc.get("solver", {}), "grid_step": 8}
    notes = inkwarp_scene(doc, face).notes()
    clash = [(p, m) for p, m in notes if "move apart" in m]
    assert [p for p, _ in clash] == ["layers[0]"] and all("'lip_upper' and 'lip_lower'" in m for _, m in clash), notes
    assert all(m.startswith("at grid_step 8, on layer ") and m.endswith("use a smaller grid_step (1 solves every pixel)")
               for _, m in clash), clash
    doc["solver"]["grid_step"] = 1
    assert inkwarp_scene(doc, face).notes() == []

    def clashes(features, width=100, step=8, border="free"):
        Image.new("RGBA", (width, 60), (200, 150, 120, 255)).save(tmp_path / "opaque.png")
        doc = {"inkwarp": 1, "fps": 4, "duration": 1, "solver": {"grid_step": step},
               "layers": [{"name": "main", "image": "opaque.png", "border": border}], "features": features}
        return [m for _, m in inkwarp_scene(doc, tmp_path).notes() if "move apart" in m]

    def line(name, x, dx):  # a vertical line at x, moved dx at the key
        return {"id": name, "kind": "polyline", "rest": [[x, 10], [x, 50]], "keys": [{"t": 0.5, "points": [[x + dx, 10], [x + dx, 50]]}]}

    # Two lines 2.5 px apart (on one coarse node) that move apart clash in the middle...
    assert [m for m in clashes([line("a", 41, -3), line("b", 43.5, 3)]) if "'a' and 'b' lie within 8 px" in m]
    # ... and alike they do not (a feature traced twice).
    assert clashes([line("a", 41, 3), line("b", 43.5, 3)]) == []
    # At the edge of a layer that holds its border, the border's own samples hold the coarse
    # nodes (as the solver's do): both lines are let go there, the picture held, no tear.
    assert [m for m in clashes([line("a", 1, -3), line("b", 3.5, 3)]) if "'a' and 'b' lie within 8 px" in m]
    assert clashes([line("a", 1, -3), line("b", 3.5, 3)], border="hold") == []
    # In the last, shorter coarse cell the solver puts them on two nodes (97.5 rounds to the
    # last, at pixel 99): no clash, though both lie within one step.
    assert clashes([line("a", 94, -3), line("b", 97.5, 3)]) == []
    # One closed outline 4 px tall that opens to 12: two parts of it meet on the coarse nodes.
    eye = {"id": "eye", "kind": "polyline", "closed": True, "rest": [[30, 28], [60, 28], [60, 32], [30, 32]],
           "keys": [{"t": 0.5, "points": [[30, 24], [60, 24], [60, 36], [30, 36]]}]}
    assert [m for m in clashes([eye]) if "two parts of 'eye'" in m]
    # A region that grows moves its inside smoothly (its interior samples are every pixel's): no note.
    square = [[30, 20], [60, 20], [60, 44], [30, 44]]
    grown = {"id": "r", "kind": "region", "rest": square, "keys": [{"t": 0.5, "points": [[45 + 1.3 * (x - 45), 32 + 1.3 * (y - 32)] for x, y in square]}]}
    assert clashes([grown]) == []


def test_the_memory_estimate_counts_thin_parts_and_a_torn_grids_slow_modes(tmp_path):
    # The solver factors a matte's thin parts exactly (nodes whose run of linked nodes along
    # the row or the column is at most 16: strands, teeth, outlines), about 1,300 bytes a
    # node, and a long solve on a torn grid keeps slow modes, 160 bytes a node (at most
    # 256 MiB, once), its solver the 4 slowest to check later claims on, 16 bytes a node
    # (each torn layer): `inkwarp_core::limits`. A comb's estimate is the opaque picture's plus all.
    opaque = np.full((HEIGHT, WIDTH, 4), 255, np.uint8)
    comb = np.zeros_like(opaque)
    comb[:20] = comb[20:, ::4] = 255  # a bar, and teeth 1 px wide below it
    runs = [np.zeros((HEIGHT, WIDTH), int), np.zeros((WIDTH, HEIGHT), int)]
    for alpha, run in zip((comb[..., 3] > 0, (comb[..., 3] > 0).T), runs):
        for row, out in zip(alpha, run):
            edges = np.flatnonzero(np.diff(np.concatenate([[0], row, [0]])))
            for start, stop in zip(edges[::2], edges[1::2]):
                out[start:stop] = stop - start
    thin = int(((comb[..., 3] > 0) & (np.minimum(runs[0], runs[1].T) <= 16)).sum())
    assert thin == (HEIGHT - 20) * len(range(0, WIDTH, 4))
    for name, picture in (("opaque.png", opaque), ("comb.png", comb)):
        Image.fromarray(picture, "RGBA").save(tmp_path / name)
    doc = {"inkwarp": 1, "fps": 4, "duration": 1, "layers": [{"name": "layer", "image": "opaque.png"}], "features": []}
    plain = inkwarp_scene(doc, tmp_path).render_bytes
    doc["layers"][0]["image"] = "comb.png"
    assert inkwarp_scene(doc, tmp_path).render_bytes - plain == thin * 1300 + WIDTH * HEIGHT * (160 + 16)
    # At grid_step 2 both count on the 25 × 21 grid the layer is solved on: the teeth keep
    # 12 × 11 nodes, and the bar, 10 nodes tall there, is thin too in the 13 columns
    # without a tooth.
    doc["solver"] = {"grid_step": 2}
    comb_bytes = inkwarp_scene(doc, tmp_path).render_bytes
    doc["layers"][0]["image"] = "opaque.png"
    assert comb_bytes - inkwarp_scene(doc, tmp_path).render_bytes == (12 * 11 + 13 * 10) * 1300 + 25 * 21 * (160 + 16)


def inkwarp_scene(doc, base):
    import inkwarp

    return inkwarp.Scene.from_dict(doc, base_dir=base)


def test_schema_prints_the_engines_schema(capsys, tmp_path):
    import inkwarp

    code, stdout, _ = run(capsys, "schema")
    assert code == 0
    assert json.loads(stdout) == inkwarp.scene_schema()
    out = tmp_path / "scene.schema.json"
    assert run(capsys, "schema", "-o", out)[0] == 0
    assert json.loads(out.read_text()) == inkwarp.scene_schema()


@pytest.mark.parametrize("args", [["-o", "m.png", "--frame", "1"], ["-o", "m.gif"],
                                  ["-o", "m.npy", "--time", "0.5"]])
def test_method_option_reaches_the_engine(capsys, scene, tmp_path, monkeypatch, args):
    import inkwarp

    seen = []
    for name in ("render", "frames", "field"):
        real = getattr(inkwarp.Scene, name)

        def spy(self, *a, _real=real, **kw):
            seen.append(kw.get("method"))
            return _real(self, *a, **kw)

        monkeypatch.setattr(inkwarp.Scene, name, spy)
    command = "field" if args[1].endswith(".npy") else "render"
    args = [tmp_path / a if a.startswith("m.") else a for a in args]
    code, _, _ = run(capsys, command, scene, *args, "--method", "tps", "-q")
    assert code == 0 and seen == ["tps"]


def test_a_method_that_ignores_holes_and_cuts_says_so_where_the_scene_has_them(capsys, tmp_path):
    # compare said it; render drew the torn surface whole without a word.
    scene = write_scene(tmp_path / "s")
    note = ("inkwarp render: note: --method triangulation ignores the continuity matte and cuts: layer 'square' "
            "stays whole across its holes and cuts (only tps tears them)\n")
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.png", "--method", "triangulation")
    assert code == 0 and err == note  # the square's transparent pixels are holes
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.png", "--method", "triangulation", "-q")
    assert code == 0 and err == ""
    picture = tmp_path / "s" / "square.png"
    opaque = np.asarray(Image.open(picture)).copy()
    opaque[..., 3] = 255
    Image.fromarray(opaque).save(picture)
    for method in ("triangulation", "tps"):
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.png", "--method", method)
        assert code == 0 and err == "", method
    doc = json.loads(scene.read_text())
    doc["features"].append({"id": "slit", "kind": "cut", "rest": [[30, 0], [30, 20]]})
    scene.write_text(json.dumps(doc))
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.png", "--method", "triangulation")
    assert code == 0 and err == note


def test_an_unknown_method_is_a_usage_error(capsys, scene, tmp_path):
    with pytest.raises(SystemExit) as stop:
        main(["render", str(scene), "-o", str(tmp_path / "m.png"), "--method", "rbf"])
    assert stop.value.code == 2
    assert "invalid choice: 'rbf'" in capsys.readouterr().err


def test_version(capsys):
    import inkwarp

    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"inkwarp {inkwarp.__version__}"


@pytest.mark.parametrize("output", ["x.png", "x.gif", "x.mp4", "frames", "f.npy"])
def test_outputs_get_the_permissions_of_any_new_file(capsys, scene, tmp_path, output):
    import os
    import stat

    old = os.umask(0o022)
    try:
        command = "field" if output.endswith(".npy") else "render"
        extra = ["--time", "0.5"] if command == "field" else []
        assert run(capsys, command, scene, "-o", tmp_path / output, "-q", *extra)[0] == 0
    finally:
        os.umask(old)
    mode = stat.S_IMODE((tmp_path / output).stat().st_mode)
    assert mode == (0o755 if output == "frames" else 0o644), oct(mode)


def test_an_output_that_is_a_layer_image_is_refused_and_the_artwork_kept(capsys, scene):
    art = scene.parent / "square.png"
    before = art.read_bytes()
    code, _, err = run(capsys, "render", scene, "-o", art, "--frame", "1")
    assert code == 2 and "square.png" in err and "would replace it" in err
    assert art.read_bytes() == before and "Traceback" not in err


def test_frames_rendered_into_the_scenes_folder_keep_a_picture_named_like_a_frame(capsys, tmp_path):
    # A layer's picture named frame_0000.png beside the scene, rendered into that folder:
    # the first frame replaced the artwork, exit 0.
    import shutil

    import inkwarp

    shutil.copy(Path(__file__).resolve().parent.parent / "examples" / "cat" / "cat.png", tmp_path / "frame_0000.png")
    assert run(capsys, "new", tmp_path / "frame_0000.png", "-o", tmp_path / "s.json", "--duration", "0.25", "-q")[0] == 0
    before = (tmp_path / "frame_0000.png").read_bytes()
    code, _, err = run(capsys, "render", tmp_path / "s.json", "-o", f"{tmp_path}/", "-q")
    assert code == 2 and "frame 0 would be written over" in err and "Render into another folder" in err, err
    with pytest.raises(ValueError, match="frame 0 would be written over"):
        inkwarp.render(inkwarp.Scene.load(tmp_path / "s.json"), tmp_path)
    # A scene built from a dict reads its pictures from its base_dir: the same check.
    doc = json.loads((tmp_path / "s.json").read_text())
    with pytest.raises(ValueError, match="frame 0 would be written over"):
        inkwarp.render(inkwarp.Scene.from_dict(doc, base_dir=tmp_path), tmp_path)
    assert (tmp_path / "frame_0000.png").read_bytes() == before
    # Frames that miss it (from 1 on) are written.
    assert run(capsys, "render", tmp_path / "s.json", "-o", f"{tmp_path}/", "--frames", "1:3", "-q")[0] == 0
    assert (tmp_path / "frame_0000.png").read_bytes() == before and (tmp_path / "frame_0002.png").exists()


def test_progress_without_a_terminal_is_an_occasional_line(capsys, tmp_path, monkeypatch):
    # A farm's log gets a line now and then, not a bar's carriage returns on one line.
    from _cli_scenes import mutated
    from inkwarp.cli import _common

    scene = write_scene(tmp_path / "s", mutated(lambda d: d.update(duration=10.0)))  # 40 frames
    now = [0.0]

    def clock():
        now[0] += 10.0  # every frame takes 10 s
        return now[0]

    monkeypatch.setattr(_common, "_clock", clock)
    code, out, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif")
    assert code == 0, err
    assert "\r" not in err
    lines = err.splitlines()
    assert err.endswith("\n") and all(line.startswith("render a.gif: ") for line in lines)
    # One line per 10 % (4 frames) when that takes over 30 s, and the last one.
    assert len(lines) == 10
    assert lines[0].startswith("render a.gif: 10% (4/40 frames in 0:40, ")
    assert lines[-1].startswith("render a.gif: 100% (40/40 frames in ")
    assert "left" in lines[0] and "left" not in lines[-1]
    # Faster frames make no more lines than one per 30 s.
    now[0] = 0.0
    monkeypatch.setattr(_common, "_clock", lambda: now.__setitem__(0, now[0] + 1.0) or now[0])
    code, out, err = run(capsys, "render", scene, "-o", tmp_path / "b.gif")
    assert code == 0 and len(err.splitlines()) == 2, err


def _slow(fps: float, duration: float | None) -> dict:
    doc = {"inkwarp": 1, "fps": fps, "layers": [{"name": "square", "image": "square.png"}]}
    return doc if duration is None else doc | {"duration": duration}


@pytest.mark.parametrize("suffix", [".webm", ".mov", ".apng", ".mp4", ".gif", ".png", "/"])
def test_a_rate_under_the_least_is_refused_by_name_before_any_output(capsys, tmp_path, suffix):
    # 1e-9 fps validated (a 1e9 s scene), then ffmpeg failed with exit status 1 on a rate
    # of 0/1 that it could not parse.
    scene = write_scene(tmp_path / "s", _slow(1e-9, None))
    code, out, err = run(capsys, "validate", scene)
    assert code == 2 and "scene.json: fps: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000, found 1e-9; use e.g. 24" in out + err, out + err
    code, out, err = run(capsys, "render", scene, "-o", f"{tmp_path / 'out'}{suffix}")
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert f"error: {scene}: fps: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000" in err and "ffmpeg" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"] and leftovers(tmp_path) == []


def test_the_slowest_rate_plays_its_time_in_every_format(capsys, tmp_path):
    # At 0.001 fps a frame lasts 1000 s: a GIF delay holds 655.35 s (the render stopped with
    # a traceback); the videos are timed by an exact rate (1/1000).
    import imageio_ffmpeg
    import subprocess

    scene = write_scene(tmp_path / "s", _slow(0.001, 2000))
    for suffix in (".gif", ".apng", ".webm", ".mov", ".mp4"):
        out = tmp_path / f"slow{suffix}"
        code, _, err = run(capsys, "render", scene, "-o", out, "-q")
        assert code == 0 and err == "", (suffix, err)
        if suffix in (".gif", ".apng"):
            with Image.open(out) as image:
                delays = []
                for i in range(image.n_frames):
                    image.seek(i)
                    delays.append(image.info["duration"])
            assert sum(delays) == 2_000_000 and max(delays) <= (655_350 if suffix == ".gif" else 1_000_000), (suffix, delays)
        else:
            said = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(out)],
                                  capture_output=True, text=True).stderr
            assert "Duration: 00:33:20.00" in said, (suffix, said)


@pytest.mark.parametrize("name", ["/dev/stdout", "/dev/stderr", "pipe", "pipe.gif"])
def test_an_output_that_is_a_stream_is_refused_by_name(capsys, tmp_path, name):
    # -o /dev/stdout said "is a file, not a directory for PNG frames".
    import os

    scene = write_scene(tmp_path / "s")
    if not name.startswith("/"):
        os.mkfifo(tmp_path / name)
        name = str(tmp_path / name)
    code, out, err = run(capsys, "render", scene, "-o", name)
    what = {"/dev/stdout": "standard output", "/dev/stderr": "standard error"}.get(name, "a pipe")
    assert code == 2 and out == "" and f"error: {name}: is {what}, not a file; inkwarp writes every output to a file" in err, err
    assert "Name a file, such as out" in err and "directory for PNG frames" not in err, err
    from inkwarp.video import open_writer

    with pytest.raises(ValueError, match=f"is {what}, not a file"):
        open_writer(name, fps=4)
