"""Scenes render: single frames, fields, and whole animations (warm-started, in parallel)."""

from __future__ import annotations

import copy
import json
import pickle
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scene_art import gradient, two_layer_scene, write_scene

import inkwarp


@pytest.fixture
def scene(tmp_path):
    return inkwarp.Scene.load(write_scene(tmp_path))


def test_properties(scene):
    assert (scene.width, scene.height, scene.fps, scene.duration, scene.frame_count) == (40, 30, 20.0, 2.0, 40)
    assert scene.layers == ["back", "front"]
    assert scene.features == ["dot", "brow", "slit"]
    np.testing.assert_array_equal(scene.times, np.arange(40) / 20)
    assert "40x30" in repr(scene)


def test_the_first_frame_is_the_picture(scene):
    # At t = 0 every feature is at rest: the front layer (opaque but for a hole) covers
    # the back one, which shows through the hole.
    frame = scene.render(time=0)
    assert frame.dtype == np.uint8 and frame.shape == (30, 40, 4)
    expected = gradient()
    np.testing.assert_array_equal(frame, expected)
    np.testing.assert_array_equal(scene.render(frame=0), frame)


def test_a_hole_shows_the_background(tmp_path):
    data = two_layer_scene()
    data["layers"] = [{"name": "front", "image": "front.png"}]
    frame = inkwarp.Scene.load(write_scene(tmp_path, data)).render()
    np.testing.assert_array_equal(frame[4, 4], [0, 0, 0, 255])  # the hole shows the background
    np.testing.assert_array_equal(frame[20, 20], gradient()[20, 20])


def test_fields_follow_the_drawing(scene):
    field = scene.field(time=1.0, layer="front")
    assert field.dtype == np.float32 and field.shape == (30, 40, 2)
    np.testing.assert_allclose(field[10, 10], [3, 1], atol=1e-4)     # the dot moved by (3, 1)
    np.testing.assert_allclose(scene.field(time=0.0, layer=1), 0, atol=1e-6)
    # Before the first key and after the last, features hold (past the scene's end, said so).
    with pytest.warns(inkwarp.PastEndWarning):
        np.testing.assert_allclose(scene.field(time=5.0, layer=0), scene.field(time=scene.duration, layer=0), atol=1e-6)
    with pytest.raises(ValueError, match="2 layers"):
        scene.field(time=1.0)
    with pytest.raises(ValueError, match="no layer is called"):
        scene.field(time=1.0, layer="nose")


def test_time_and_frame_arguments(scene):
    np.testing.assert_array_equal(scene.render(frame=20), scene.render(time=1.0))
    with pytest.raises(ValueError, match="not both"):
        scene.render(time=1, frame=2)
    with pytest.raises(ValueError, match="out of range"):
        scene.render(frame=40)
    with pytest.raises(ValueError, match="finite"):
        scene.render(time=float("nan"))
    # Past the times a scene holds (its warnings named frame 2^64 - 1 at 1e300 s).
    for t in (1e300, -2e5):
        with pytest.raises(ValueError, match=r"past the times a scene holds \(±100000 s"):
            scene.render(time=t)
        with pytest.raises(ValueError, match="past the times a scene holds"):
            scene.field(time=t, layer=0)


def test_a_moving_point_moves_the_picture(tmp_path):
    # One layer, one point translated by a whole number of pixels: the picture moves by
    # that much near the point.
    data = {
        "inkwarp": 1, "fps": 1, "duration": 2,
        "layers": [{"name": "only", "image": "back.png"}],
        "features": [{"id": "p", "kind": "point", "rest": [[20, 15]],
                      "keys": [{"t": 0, "points": [[20, 15]]}, {"t": 1, "points": [[22, 15]]}]}],
    }
    scene = inkwarp.Scene.load(write_scene(tmp_path, data))
    moved = scene.render(time=1.0)
    np.testing.assert_array_equal(moved[15, 22], gradient()[15, 20])


def test_warm_started_frames_match_cold_frames(scene):
    warm = list(scene.frames(threads=1))
    assert len(warm) == scene.frame_count
    for i in (1, 7, 15, 17, 30, 39):
        cold = scene.render(frame=i)
        diff = np.abs(warm[i].astype(int) - cold.astype(int))
        # Fields agree within the solver tolerance, so pixels differ by little and rarely.
        assert diff.mean() < 0.5, (i, diff.mean())


def test_parallel_and_sequential_frames_are_identical(scene):
    sequential = list(scene.frames(threads=1))
    parallel = list(scene.frames(threads=3))
    assert len(sequential) == len(parallel) == 40
    for a, b in zip(sequential, parallel):
        np.testing.assert_array_equal(a, b)


def test_frames_iterator(scene):
    frames = scene.frames(5, 12, threads=2)
    assert len(frames) == 7
    first = next(frames)
    assert frames.index == 5 and len(frames) == 6
    # The frame a sequential render gives (frames 0 to 4 are solved first and dropped).
    np.testing.assert_array_equal(first, list(scene.frames(0, 6, threads=1))[5])
    frames.close()
    assert list(frames) == []
    with scene.frames(threads=2) as frames:
        next(frames)
    assert len(scene.frames(38)) == 2
    assert len(scene.frames(0, 1000)) == 40
    with pytest.raises(ValueError):
        scene.frames(10, 5)


def test_to_dict_round_trips_and_fills_defaults(scene, tmp_path):
    data = scene.to_dict()
    assert data["solver"] == {"method": "tps", "tension": 0.0, "tolerance": 0.01, "grid_step": 1, "scheme": "multigrid"}
    again = inkwarp.Scene.from_dict(data, base_dir=tmp_path)
    assert again.to_dict() == data
    assert scene.validate() == []


def test_save_rewrites_relative_image_paths(scene, tmp_path):
    (tmp_path / "elsewhere").mkdir()
    target = tmp_path / "elsewhere" / "copy.json"
    scene.save(target)
    saved = json.loads(target.read_text())
    assert saved["layers"][0]["image"] == "../back.png"
    np.testing.assert_array_equal(inkwarp.Scene.load(target).render(time=0.7), scene.render(time=0.7))


def test_a_scene_built_in_the_current_folder_saves_elsewhere(scene, tmp_path, monkeypatch):
    # from_dict and from_json without base_dir read images from the current folder; a save
    # to another folder rewrites their paths from there, as it does with base_dir given.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "elsewhere").mkdir()
    for built in (inkwarp.Scene.from_dict(scene.to_dict()), inkwarp.Scene.from_json(json.dumps(scene.to_dict()))):
        built.save("elsewhere/copy.json")
        assert json.loads((tmp_path / "elsewhere" / "copy.json").read_text())["layers"][0]["image"] == "../back.png"
        np.testing.assert_array_equal(inkwarp.Scene.load("elsewhere/copy.json").render(time=0.7), scene.render(time=0.7))


def test_data_uri_images(tmp_path):
    data = two_layer_scene()
    data["layers"][0]["image"] = inkwarp.image_data_uri(gradient())
    data["layers"][1]["image"] = inkwarp.image_data_uri(np.asarray(Image.fromarray(gradient()).convert("RGB")))
    scene = inkwarp.Scene.from_dict(data)
    np.testing.assert_array_equal(scene.render(), gradient())


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_a_scene_pickles_and_copies_to_one_that_renders_the_same_frames(tmp_path, monkeypatch):
    # Process pools pickle their arguments; the engine's scene itself cannot be pickled.
    face = inkwarp.Scene.load(EXAMPLES / "face" / "scene.json")
    copied = pickle.loads(pickle.dumps(face))
    assert (copied.file, copied.base_dir, copied.to_dict()) == (face.file, face.base_dir, face.to_dict())
    np.testing.assert_array_equal(copied.render(time=0.7), face.render(time=0.7))
    np.testing.assert_array_equal(copy.deepcopy(face).render(frame=30), face.render(frame=30))
    # Relative image paths of a scene built in the current folder are read from that folder
    # wherever the copy is unpickled; data: URIs travel in the pickle.
    write_scene(tmp_path)
    monkeypatch.chdir(tmp_path)
    data = two_layer_scene()
    data["layers"][1]["image"] = inkwarp.image_data_uri(gradient(hole=(slice(2, 8), slice(2, 8))))
    built = inkwarp.Scene.from_dict(data)
    pickled = pickle.dumps(built)
    monkeypatch.chdir(EXAMPLES)
    np.testing.assert_array_equal(pickle.loads(pickled).render(time=0.7), built.render(time=0.7))
    np.testing.assert_array_equal(copy.deepcopy(built).render(time=0.7), built.render(time=0.7))


def test_a_scene_renders_in_a_process_pool():
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    face = inkwarp.Scene.load(EXAMPLES / "face" / "scene.json")
    # Spawned, so the scene goes through pickle (a forked worker could share it).
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        frame = pool.submit(face.render, time=0.7).result(timeout=120)
    np.testing.assert_array_equal(frame, face.render(time=0.7))


@pytest.mark.parametrize("kind", [inkwarp.Solver, inkwarp.WarmStart])
def test_solvers_and_warm_starts_pickle_and_copy_as_fresh_ones(kind):
    # What they hold is a cache of the engine's: a copy starts empty and solves the same.
    pts, disp = [[8, 8], [56, 8], [8, 40], [56, 40], [32, 24]], [[0, 0]] * 4 + [[3, 0]]
    used = kind()
    keyword = "solver" if kind is inkwarp.Solver else "warm"
    inkwarp.thin_plate(pts, disp, (48, 64), **{keyword: used})
    fresh = inkwarp.thin_plate(pts, disp, (48, 64))
    for copied in (pickle.loads(pickle.dumps(used)), copy.deepcopy(used), copy.copy(used)):
        assert type(copied) is kind and copied is not used
        if kind is inkwarp.WarmStart:
            assert len(used) == 1 and len(copied) == 0
        np.testing.assert_array_equal(inkwarp.thin_plate(pts, disp, (48, 64), **{keyword: copied}), fresh)


def test_the_method_can_be_chosen_per_call(scene):
    np.testing.assert_array_equal(scene.render(time=0.7, method="tps"), scene.render(time=0.7))
    np.testing.assert_array_equal(scene.field(time=0.7, layer=0, method="tps"), scene.field(time=0.7, layer=0))
    with pytest.raises(ValueError, match='unknown method "rbf"; use one of "tps"'):
        scene.render(time=0.7, method="rbf")
    # Not a name at all: a ValueError naming the argument (it was the binding's TypeError).
    for call in (lambda: scene.render(method=5), lambda: scene.field(layer=0, method=b"tps"), lambda: scene.frames(method=5)):
        with pytest.raises(ValueError, match="method must be one of 'tps', 'tps-exact'"):
            call()
    with pytest.raises(ValueError, match="base_dir must be a path"):
        inkwarp.Scene.from_dict(scene.to_dict(), base_dir=5)
    assert len(list(scene.frames(0, 3, method="tps"))) == 3


@pytest.mark.parametrize("closed", [True, False])
def test_a_closed_cut_frees_what_it_encloses(closed):
    # A cut with "closed" runs back to its first point: the square inside it is a piece of
    # its own, which no feature holds, so it stays where it is while the rest follows the
    # points. Left open, the fourth side joins the square to the rest, which pulls it along.
    square = [[20.5, 20.5], [43.5, 20.5], [43.5, 43.5], [20.5, 43.5]]
    doc = {"inkwarp": 1, "width": 64, "height": 64, "duration": 1, "layers": [{"name": "a"}],
           "features": [{"id": "loop", "kind": "cut", "closed": closed, "rest": square}] + [
               {"id": f"p{i}", "kind": "point", "rest": [p], "keys": [{"t": 0, "points": [[p[0] + 4, p[1]]]}]}
               for i, p in enumerate([[5, 5], [58, 5], [5, 58]])]}
    field = inkwarp.Scene.from_dict(doc).field(0)
    assert np.allclose(field[5, 58], [4, 0], atol=0.02) and np.allclose(field[58, 58], [4, 0], atol=0.05)
    inside = field[22:43, 22:43]
    if closed:
        assert np.abs(inside).max() == 0
    else:
        assert np.allclose(inside, [4, 0], atol=0.05)


def test_save_writes_only_json_names(scene, tmp_path):
    # A slip of the name must not replace a picture (the scene's own, here) with text.
    picture = tmp_path / "back.png"
    before = picture.read_bytes()
    with pytest.raises(ValueError, match=r"back\.png: a scene is saved as JSON; name the file \.json, such as back\.json"):
        scene.save(picture)
    assert picture.read_bytes() == before
    scene.save(tmp_path / "Copy.JSON")
    assert inkwarp.Scene.load(tmp_path / "Copy.JSON").to_dict() == scene.to_dict()
    for wrong in (None, 3, b"copy.json"):  # a ValueError naming the argument, not pathlib's TypeError
        with pytest.raises(ValueError, match=rf"Scene.save's path must be a path .*; got {type(wrong).__name__}"):
            scene.save(wrong)


def test_a_time_past_the_end_or_before_0_and_every_key_warns_as_the_command_line_does(scene):
    # `inkwarp render --time 100` warned that it was past the scene's end; Scene.render(time=100)
    # said nothing. A time before 0 is the drawing before the first frame (keys may lie there:
    # then no warning), and before every key it is the first keys' poses held, said so.
    import warnings

    end = scene.duration
    with pytest.warns(inkwarp.PastEndWarning, match=rf"time 100 s is past the scene's end \({end:g} s\): it shows the poses held") as said:
        late = scene.render(time=100)
    assert said[0].filename == __file__  # the warning names the caller's line
    with pytest.warns(inkwarp.PastEndWarning, match="past the scene's end"):
        scene.field(time=end + 0.5, layer=0)
    assert issubclass(inkwarp.PastEndWarning, inkwarp.InkwarpWarning)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(scene.render(time=end), late)  # the end itself: no warning
        scene.render(frame=scene.frame_count - 1)
    with pytest.warns(inkwarp.PastEndWarning, match=r"time -1 s is before the scene's start \(0 s\)") as said:
        early = scene.render(time=-1)
    assert said[0].filename == __file__
    np.testing.assert_array_equal(early, scene.render(time=0))  # the first keys held
    with pytest.raises(ValueError, match=r"time -200000 s is past the times a scene holds"):
        scene.render(time=-2e5)
