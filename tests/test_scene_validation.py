"""Every kind of mistake in a scene gives an inkwarp.SceneError naming the file and the
JSON path of the problem, and all problems are reported at once."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from PIL import Image
from scene_art import gradient, two_layer_scene, write_scene

import inkwarp


def changed(pointer: str, value):
    """The two-layer scene with the value at `pointer` (a/b/0/c) set."""
    scene = copy.deepcopy(two_layer_scene())
    *parents, last = pointer.split("/")
    target = scene
    for part in parents:
        target = target[int(part)] if isinstance(target, list) else target[part]
    if isinstance(target, list) and int(last) == len(target):
        target.append(value)
    elif isinstance(target, list):
        target[int(last)] = value
    else:
        target[last] = value
    return scene


MISTAKES = [
    ("unknown kind", changed("features/0/kind", "circle"), "features[0].kind", '"point", "polyline"'),
    ("wrong control-point count", changed("features/1/keys/1/points", [[1, 1]]), "features[1].keys[1].points", "rest has 3"),
    ("too few points", changed("features/1", {"id": "brow", "kind": "spline", "rest": [[1, 1]]}), "features[1].rest", "at least 2"),
    ("region with two points", changed("features/1", {"id": "brow", "kind": "region", "rest": [[1, 1], [5, 5]]}), "features[1].rest", "at least 3"),
    ("keys out of order", changed("features/0/keys/1/t", 5), "features[0].keys[2].t", "sort the keys"),
    ("keys at equal times", changed("features/0/keys/1/t", 0), "features[0].keys[1].t", "two keys at t = 0"),
    ("unknown feature id", changed("layers/1/features/1", "brw"), "layers[1].features[1]", 'did you mean "brow"'),
    ("duplicate id", changed("features/3", {"id": "dot", "kind": "point", "rest": [[1, 1]]}), "features[3].id", "already used"),
    ("negative tension", changed("solver", {"tension": -0.1}), "solver.tension", "at least 0"),
    ("zero fps", changed("fps", 0), "fps", "from 0.001 (one frame every 1000 s) to 1000, found 0.0"),
    # A billionth of a frame a second validated, then failed in ffmpeg (a rate of 0/1).
    ("fps below the least", changed("fps", 1e-9), "fps", "from 0.001 (one frame every 1000 s) to 1000, found 1e-9"),
    ("zero duration", changed("duration", 0), "duration", "> 0"),
    ("bad grid step", changed("solver", {"grid_step": 0}), "solver.grid_step", "at least 1"),
    ("fractional grid step", changed("solver", {"grid_step": 2.5}), "solver.grid_step", "whole number"),
    ("unknown method", changed("solver", {"method": "rbf"}), "solver.method", "tps"),
    ("unknown key", changed("layers/0/opacity", 0.5), "layers[0].opacity", "unknown key"),
    ("misspelt key", changed("features/0/keyz", []), "features[0].keyz", 'did you mean "keys"'),
    ("wrong version", changed("inkwarp", 2), "inkwarp", "scene format 1"),
    ("string for a number", changed("features/0/rest/0/1", "10"), "features[0].rest[0][1]", "expected a number"),
    ("missing image", changed("layers/0/image", "nowhere.png"), "layers[0].image", "a relative path is read from the scene's folder"),
    ("windows path", changed("layers/0/image", "art\\face.png"), "layers[0].image", "write the path with forward slashes (art/cat.png)"),
    ("file uri", changed("layers/0/image", "file:///home/me/face.png"), "layers[0].image", "give a path, not a file: URI"),
    ("negative layer tension", changed("layers/1/solver", {"tension": -2}), "layers[1].solver.tension", "at least 0"),
    ("no layers", changed("layers", []), "layers", "at least one layer"),
    ("a width alone, not the images'", changed("width", 50), "width", "50 does not match the images, which are 40×30"),
    ("a height alone, not the images'", changed("height", 31), "height", "31 does not match the images, which are 40×30"),
    ("features past the limit in a layer's pixels", changed("layers/1/offset", [0, -1e6]), "layers[1].offset", 'feature "dot" lies more than 1e6 px'),
    ("a width alone, no image", changed("layers", [{"name": "plain"}]) | {"width": 64}, "height", 'no layer has an image to take the frame size from'),
]


@pytest.mark.parametrize(("what", "scene", "path", "words"), MISTAKES, ids=[m[0] for m in MISTAKES])
def test_each_mistake_names_its_path_and_file(tmp_path, what, scene, path, words):
    file = write_scene(tmp_path, scene)
    with pytest.raises(inkwarp.SceneError) as caught:
        inkwarp.Scene.load(file)
    err = caught.value
    assert err.path == path, err.problems
    assert [p for p, _ in err.problems] == [path]
    assert words in err.problems[0][1]
    assert err.file == str(file)
    assert str(err).startswith(f"{file}: {path}: ")
    assert isinstance(err, ValueError)
    # The same mistake in a dict, and from the non-raising validator.
    with pytest.raises(inkwarp.SceneError) as caught:
        inkwarp.Scene.from_dict(scene, base_dir=tmp_path)
    assert caught.value.path == path and caught.value.file is None
    assert [p for p, _ in inkwarp.validate_scene(file)] == [path]


def test_every_problem_is_reported_at_once(tmp_path):
    scene = changed("fps", -1)
    scene["features"][0]["kind"] = "circle"
    scene["features"][1]["keys"][0]["points"] = [[0, 0]]
    scene["layers"][0]["image"] = "missing.png"
    scene["layers"][1]["features"] = ["nobody", "brow"]
    with pytest.raises(inkwarp.SceneError) as caught:
        inkwarp.Scene.load(write_scene(tmp_path, scene))
    paths = sorted(p for p, _ in caught.value.problems)
    assert paths == ["features[0].kind", "features[1].keys[0].points", "fps", "layers[0].image", "layers[1].features[0]"]
    assert str(caught.value).count("\n") == 5


def test_a_misspelt_feature_id_is_matched_to_a_feature_that_could_not_be_read():
    # "brow" has a misspelt kind, so it is set aside; "brw" in the layer still means it.
    scene = changed("features/1/kind", "splin")
    scene["layers"][1]["features"] = ["dot", "brw"]
    problems = dict(inkwarp.validate_scene(scene))
    assert 'did you mean "brow"?' in problems["layers[1].features[1]"], problems
    assert '"spline"' in problems["features[1].kind"], problems


def test_a_point_past_the_limit_is_named_once_not_also_at_its_layers_offset():
    scene = changed("features/0/rest", [[1e300, 1]])
    assert [path for path, _ in inkwarp.validate_scene(scene) if "image" not in path] == ["features[0].rest[0][0]"]


def test_invalid_json_gives_line_and_column(tmp_path):
    file = tmp_path / "scene.json"
    file.write_text('{"inkwarp": 1,\n  "layers": [\n}')
    with pytest.raises(inkwarp.SceneError, match="line 3 column 1") as caught:
        inkwarp.Scene.load(file)
    assert caught.value.path == ""


def test_a_missing_scene_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        inkwarp.Scene.load(tmp_path / "absent.json")
    assert inkwarp.validate_scene(tmp_path / "absent.json")[0][1].startswith("no such scene file")


def test_images_of_the_wrong_size(tmp_path):
    file = write_scene(tmp_path)
    Image.fromarray(gradient(20, 30)).save(tmp_path / "front.png")
    with pytest.raises(inkwarp.SceneError, match=r"20×30 pixels but the scene is 40×30 \(from layers\[0\]\.image\)") as caught:
        inkwarp.Scene.load(file)
    assert caught.value.path == "layers[1].image"


def test_mattes_of_the_wrong_size_and_unreadable_images(tmp_path):
    Image.fromarray(np.full((10, 10), 255, np.uint8)).save(tmp_path / "matte.png")
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n not really")
    (tmp_path / "text.png").write_text("hello")
    scene = changed("layers/0/continuity", "matte.png")
    scene["layers"][1]["alpha"] = "broken.png"
    scene["layers"][1]["continuity"] = "text.png"
    with pytest.raises(inkwarp.SceneError) as caught:
        inkwarp.Scene.load(write_scene(tmp_path, scene))
    problems = dict(caught.value.problems)
    assert set(problems) == {"layers[0].continuity", "layers[1].alpha", "layers[1].continuity"}
    assert "10×10" in problems["layers[0].continuity"]
    assert "could not be decoded" in problems["layers[1].alpha"]
    assert "not a PNG or JPEG" in problems["layers[1].continuity"]


def test_a_jpeg_cut_short_is_refused_and_one_with_data_after_its_end_is_not(tmp_path):
    # A JPEG cut short (a half-synced file on a share) decoded without an error, the rest of
    # the picture grey. Data after the end marker (a motion photo's video, which may hold
    # FF DA) must not make a whole file look cut short.
    import io

    picture = Image.fromarray(gradient(40, 30)[..., :3])
    files = {}
    for name, options in (("baseline", {}), ("progressive", {"progressive": True})):
        data = io.BytesIO()
        picture.save(data, "JPEG", quality=90, **options)
        files[name] = data.getvalue()
    trailer = np.random.default_rng(1).bytes(200_000) + b"\xff\xda\x00\x0c" + bytes(40)
    whole = {"baseline.jpg": files["baseline"], "progressive.jpg": files["progressive"],
             "motion.jpg": files["baseline"] + trailer}
    cut = {"half.jpg": files["baseline"][: len(files["baseline"]) // 2],
           "late.jpg": files["progressive"][: len(files["progressive"]) * 9 // 10],
           "no_end.jpg": files["baseline"][:-2]}
    for name, data in {**whole, **cut}.items():
        (tmp_path / name).write_bytes(data)
        scene = {"inkwarp": 1, "layers": [{"name": "a", "image": name}]}
        problems = inkwarp.Scene.from_dict(scene, base_dir=tmp_path).validate() if name in whole else None
        if name in whole:
            assert problems == [], (name, problems)
        else:
            with pytest.raises(inkwarp.SceneError, match="is a JPEG that ends before its end-of-image marker: "
                               "the file is cut short"):
                inkwarp.Scene.from_dict(scene, base_dir=tmp_path)


def test_bad_data_uris(tmp_path):
    scene = changed("layers/0/image", "data:image/png;base64,%%%")
    scene["layers"][1]["image"] = "data:image/png,plain"
    with pytest.raises(inkwarp.SceneError) as caught:
        inkwarp.Scene.from_dict(scene, base_dir=tmp_path)
    problems = dict(caught.value.problems)
    assert "not valid base64" in problems["layers[0].image"]
    assert "only base64" in problems["layers[1].image"]


def test_non_finite_numbers_in_a_dict(tmp_path):
    write_scene(tmp_path)
    scene = changed("features/0/rest", np.array([[math.nan, 3.0]]))
    scene["layers"][1]["offset"] = [0, float("inf")]
    scene["fps"] = 0
    with pytest.raises(inkwarp.SceneError) as caught:
        inkwarp.Scene.from_dict(scene, base_dir=tmp_path)
    problems = dict(caught.value.problems)
    assert sorted(problems) == ["features[0].rest[0][0]", "fps", "layers[1].offset[1]"]
    assert "finite" in problems["features[0].rest[0][0]"]


def test_numpy_values_are_accepted(tmp_path):
    write_scene(tmp_path)
    scene = two_layer_scene()
    scene["features"][0]["rest"] = np.array([[10, 10]], dtype=np.int64)
    scene["fps"] = np.float32(20)
    assert inkwarp.Scene.from_dict(scene, base_dir=tmp_path).frame_count == 40


def test_image_paths_are_relative_to_the_scene_file(tmp_path):
    (tmp_path / "art").mkdir()
    (tmp_path / "scenes").mkdir()
    write_scene(tmp_path / "art")
    scene = two_layer_scene()
    for layer in scene["layers"]:
        layer["image"] = "../art/" + layer["image"]
    file = tmp_path / "scenes" / "s.json"
    file.write_text(json.dumps(scene))
    assert inkwarp.Scene.load(file).layers == ["back", "front"]


def test_a_byte_order_mark_is_fine(tmp_path):
    file = write_scene(tmp_path)
    file.write_bytes(b"\xef\xbb\xbf" + file.read_bytes())
    assert inkwarp.Scene.load(file).frame_count == 40
    assert inkwarp.validate_scene(file) == []


@pytest.mark.parametrize("key, value", [("width", 40), ("height", 30)])
def test_a_width_or_height_alone_that_matches_the_images_is_fine(tmp_path, key, value):
    scene = inkwarp.Scene.load(write_scene(tmp_path, {**two_layer_scene(), key: value}))
    assert (scene.width, scene.height) == (40, 30)
