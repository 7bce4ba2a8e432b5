"""Animation transfer: the target's keys are the source's keys through the rest-to-rest
thin-plate map."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

import inkwarp
from inkwarp.cli import main


def face_scene():
    """A small source drawing with keys of every curve kind."""
    return {
        "inkwarp": 1,
        "width": 120,
        "height": 100,
        "fps": 12,
        "duration": 2.0,
        "layers": [{"name": "face", "image": "face.png"}],
        "features": [
            {"id": "nose", "kind": "point", "rest": [[60, 50]],
             "keys": [{"t": 0.5, "points": [[62, 52]]}, {"t": 1.5, "points": [[58, 47]]}]},
            {"id": "mouth", "kind": "spline", "rest": [[40, 75], [60, 82], [80, 75]],
             "keys": [{"t": 1.0, "points": [[40, 77], [60, 90], [80, 77]], "interpolation": "linear"}]},
            {"id": "brow", "kind": "polyline", "rest": [[30, 30], [50, 24], [55, 36]],
             "keys": [{"t": 1.0, "points": [[30, 26], [50, 18], [55, 33]]}]},
            {"id": "cheek", "kind": "region", "rest": [[80, 40], [95, 45], [90, 60], [78, 55]], "closed": True,
             "keys": [{"t": 2.0, "points": [[81, 41], [97, 44], [92, 61], [79, 57]]}]},
            {"id": "gap", "kind": "cut", "rest": [[10, 10], [20, 20]]},
        ],
    }


def retraced(scene, f):
    """The same features traced at f(rest), without keys."""
    out = json.loads(json.dumps(scene))
    for feature in out["features"]:
        feature["rest"] = [list(map(float, f(np.array(p, float)))) for p in feature["rest"]]
        feature["keys"] = []
    return out


def all_keys(scene):
    return {f["id"]: [(k["t"], np.array(k["points"], float)) for k in f.get("keys", [])] for f in scene["features"]}


def test_identical_rest_drawings_give_identical_keys():
    source = face_scene()
    out = inkwarp.transfer_dict(source, retraced(source, lambda p: p))
    got, want = all_keys(out), all_keys(source)
    for fid, keys in want.items():
        if fid == "gap":
            continue
        assert [t for t, _ in got[fid]] == [t for t, _ in keys]
        for (_, g), (_, w) in zip(got[fid], keys):
            np.testing.assert_allclose(g, w, atol=1e-9)
    # Interpolation modes travel with the keys.
    assert out["features"][1]["keys"][0]["interpolation"] == "linear"


def test_affine_target_gets_the_affine_image_of_the_keys():
    m, t = np.array([[1.4, 0.25], [-0.1, 0.8]]), np.array([15.0, -6.0])
    affine = lambda p: m @ p + t  # noqa: E731
    source = face_scene()
    out = inkwarp.transfer_dict(source, retraced(source, affine))
    got = all_keys(out)
    for fid, keys in all_keys(source).items():
        if fid == "gap":
            continue
        for (_, g), (_, w) in zip(got[fid], keys):
            np.testing.assert_allclose(g, w @ m.T + t, atol=1e-8)


def test_a_non_affine_target_moves_keys_with_it():
    # The target bulges: keys still land near the target's own rest, displaced by about
    # the source's displacement scaled locally.
    source = face_scene()
    bulge = lambda p: p + 0.15 * (p - [60, 50]) * np.exp(-np.sum((p - [60, 50]) ** 2) / 2000)  # noqa: E731
    out = inkwarp.transfer_dict(source, retraced(source, bulge))
    nose_key = np.array(out["features"][0]["keys"][0]["points"][0])
    assert np.linalg.norm(nose_key - np.array([62, 52])) < 1.5


def test_features_only_in_the_target_keep_their_keys():
    source = face_scene()
    target = retraced(source, lambda p: p + 3)
    target["features"].append({"id": "tail", "kind": "point", "rest": [[5, 90]],
                               "keys": [{"t": 0.3, "points": [[6, 92]]}]})
    out = inkwarp.transfer_dict(source, target)
    assert out["features"][-1]["keys"] == [{"t": 0.3, "points": [[6, 92]]}]


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda s: s["features"].pop(1), r'Feature "mouth" \(source features\[1\]\) is not in the target'),
        (lambda s: s["features"][2].update(kind="spline"),
         r'Feature "brow" is a polyline in the source \(features\[2\]\) but a spline in the target'),
        (lambda s: s["features"][3]["rest"].pop(),
         r'Feature "cheek" has 4 rest control points in the source .* but 3 in the target .*; '
         r"give the target's feature 4 control points .*or leave the feature out of the source"),
    ],
)
def test_mismatches_are_errors_naming_the_feature(change, message):
    source = face_scene()
    target = retraced(source, lambda p: p)
    change(target)
    with pytest.raises(ValueError, match=message):
        inkwarp.transfer_dict(source, target)


def test_cli_writes_the_transferred_scene_with_image_paths_that_still_resolve(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    source = face_scene()
    target = retraced(source, lambda p: 1.2 * p)
    target["layers"][0]["image"] = "cat.png"
    (tmp_path / "a" / "face.json").write_text(json.dumps(source))
    (tmp_path / "b" / "cat.json").write_text(json.dumps(target))
    out = tmp_path / "out" / "cat_animated.json"
    out.parent.mkdir()  # (a missing folder is refused, as by every command)
    code = main(["transfer", "--source", str(tmp_path / "a" / "face.json"),
                 "--target", str(tmp_path / "b" / "cat.json"), "-o", str(out), "--quiet"])
    assert code == 0
    doc = json.loads(out.read_text())
    assert doc["layers"][0]["image"] == "../b/cat.png"
    np.testing.assert_allclose(doc["features"][0]["keys"][0]["points"], [[1.2 * 62, 1.2 * 52]], atol=1e-8)


def test_cli_bad_input_exits_2_with_one_line_and_no_output(tmp_path, capsys):
    source = face_scene()
    target = retraced(source, lambda p: p)
    target["features"].pop(0)
    (tmp_path / "s.json").write_text(json.dumps(source))
    (tmp_path / "t.json").write_text(json.dumps(target))
    out = tmp_path / "o.json"
    code = main(["transfer", "--source", str(tmp_path / "s.json"), "--target", str(tmp_path / "t.json"),
                 "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and 'Feature "nose"' in err
    # The files come first, as in every message about a file.
    assert err.startswith(f"inkwarp transfer: error: {tmp_path / 's.json'} → {tmp_path / 't.json'}: Feature"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json", "t.json"]


def test_cli_names_a_picture_a_folder_or_a_scene_mistake_as_every_command_does(tmp_path, capsys):
    # A picture given as a scene gave Python's "'utf-8' codec can't decode byte 0x89", a
    # folder a bare "Is a directory", and an invalid scene one problem with no place.
    source = face_scene()
    (tmp_path / "s.json").write_text(json.dumps(source))
    (tmp_path / "p.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    bad = retraced(source, lambda p: p)
    bad["features"][1]["kind"], bad["fps"] = "x", 0
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    (tmp_path / "twice.json").write_text(json.dumps(source).replace('"fps": ', '"fps": 12, "fps": ', 1))
    for source_arg, target_arg, says in [
        (tmp_path / "twice.json", tmp_path / "s.json", "twice.json: fps: given more than once in its object"),
        (tmp_path / "p.png", tmp_path / "s.json", "p.png: a PNG picture, not a scene; make a scene of it with inkwarp new"),
        (tmp_path, tmp_path / "s.json", "not a regular file (a folder, FIFO or device); give a scene's JSON file"),
        (tmp_path / "s.json", tmp_path / "bad.json", 'bad.json: features[1].kind: unknown kind "x"'),
    ]:
        code = main(["transfer", "--source", str(source_arg), "--target", str(target_arg), "-o", str(tmp_path / "o.json")])
        err = capsys.readouterr().err
        assert code == 2 and says in err and err.count("\n") == 1, err
    assert "(and 1 more problem" in err
    assert not (tmp_path / "o.json").exists()


def test_cli_missing_file_exits_2(tmp_path, capsys):
    code = main(["transfer", "--source", str(tmp_path / "nope.json"), "--target", str(tmp_path / "nope.json"),
                 "-o", str(tmp_path / "o.json")])
    assert code == 2
    assert "does not exist" in capsys.readouterr().err


ROOT = Path(__file__).resolve().parents[1]


def test_the_transfer_example_is_up_to_date_and_renders(tmp_path):
    committed = json.loads((ROOT / "examples" / "transfer" / "cat-animated.json").read_text())
    fresh = inkwarp.transfer_dict(ROOT / "examples" / "face" / "scene.json",
                                  ROOT / "examples" / "transfer" / "cat-target.json",
                                  relative_to=ROOT / "examples" / "transfer")
    assert fresh == committed, "run: inkwarp transfer (see examples/transfer/README.md)"
    from inkwarp.transfer import transfer_example

    scene = inkwarp.Scene.load(transfer_example(ROOT / "examples", tmp_path))
    assert scene.render(time=1.0).shape == (300, 451, 4)
    # Every face feature is animated on the cat; the cat's own border holds still.
    keys = {f["id"]: f.get("keys", []) for f in committed["features"]}
    assert keys["lid_l_upper"] and keys["pupil_r"] and not keys["frame"]


def test_transfer_returns_a_scene(tmp_path):
    scene = inkwarp.transfer(ROOT / "examples" / "face" / "scene.json",
                             ROOT / "examples" / "transfer" / "cat-target.json")
    assert isinstance(scene, inkwarp.Scene)
    assert (scene.width, scene.height) == (451, 300)
    # Saved, its pictures are relative to where it goes, as `inkwarp transfer -o` writes
    # them (they were absolute paths: a folder moved or sent to a farm lost them).
    (tmp_path / "shot").mkdir()
    scene.save(tmp_path / "shot" / "cat.json")
    saved = json.loads((tmp_path / "shot" / "cat.json").read_text())
    cat = (ROOT / "examples" / "cat").resolve()
    assert [layer["image"] for layer in saved["layers"]] == [
        os.path.relpath(cat / Path(layer["image"]).name, tmp_path / "shot") for layer in saved["layers"]]
    assert inkwarp.Scene.load(tmp_path / "shot" / "cat.json").render(time=1.0).shape == (300, 451, 4)


EXAMPLE = ROOT / "examples" / "transfer"


def _example_docs():
    face = json.loads((ROOT / "examples" / "face" / "scene.json").read_text())
    cat = json.loads((EXAMPLE / "cat-target.json").read_text())
    return face, cat


def test_the_transfer_example_target_is_what_its_script_draws():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_target", EXAMPLE / "make_target.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    committed = json.loads((EXAMPLE / "cat-target.json").read_text())
    assert module.scene() == committed, "run: python examples/transfer/make_target.py"


def test_the_transfer_example_map_keeps_its_orientation_over_the_face():
    # A matched curve traced the other way round (the cat's left brow once ran outer to
    # inner, the face's inner to outer) folds the map over on itself, and every key with
    # it: the determinant of W's Jacobian goes negative near the feature.
    face, cat = _example_docs()
    by_id = {f["id"]: f for f in cat["features"]}
    shared = [f for f in face["features"] if f["kind"] != "cut"]
    w = inkwarp.ThinPlateMap([p for f in shared for p in f["rest"]],
                             [p for f in shared for p in by_id[f["id"]]["rest"]])
    head = np.array(next(f for f in face["features"] if f["id"] == "head")["rest"])
    lo, hi = head.min(axis=0), head.max(axis=0)
    ys, xs = np.mgrid[lo[1]:hi[1]:2.0, lo[0]:hi[0]:2.0]
    p = np.stack([xs.ravel(), ys.ravel()], axis=1)
    h = 0.5
    d_dx = (w(p + [h, 0]) - w(p - [h, 0])) / (2 * h)
    d_dy = (w(p + [0, h]) - w(p - [0, h])) / (2 * h)
    det = d_dx[:, 0] * d_dy[:, 1] - d_dx[:, 1] * d_dy[:, 0]
    assert det.min() > 0.1, f"W folds near {p[det.argmin()].tolist()} (det {det.min():.2f})"


def test_the_transfer_example_lids_follow_the_cats_traced_lids():
    # The 5-point lids must lie on the fur just outside the eye holes, as the cat's own
    # 9-point lids (which the holes were cut inside) do.
    from inkwarp import _inkwarp

    def curve(points):
        doc = {"inkwarp": 1, "width": 8, "height": 8, "layers": [{"name": "a"}],
               "features": [{"id": "c", "kind": "spline", "rest": points}]}
        return np.asarray(_inkwarp.posed_drawing(json.dumps(doc), 0.0, 0.5)[0][2])

    _, cat = _example_docs()
    traced = {f["id"]: f["rest"] for f in json.loads((ROOT / "examples" / "cat" / "scene.json").read_text())["features"]}
    for f in cat["features"]:
        if f["id"].startswith("lid_"):
            a, b = curve(f["rest"]), curve(traced[f["id"]])
            d = np.hypot(*(a[:, None, :] - b[None, :, :]).transpose(2, 0, 1))
            assert max(d.min(axis=0).max(), d.min(axis=1).max()) < 0.8, f["id"]


def test_the_transferred_cat_shuts_its_eyes_at_the_blink():
    # The fur layer alone over magenta: the eye holes show as magenta when open, and the
    # closed lids cover them completely at the face's blink (t = 1.05 s).
    doc = json.loads((EXAMPLE / "cat-animated.json").read_text())
    doc["background"] = [255, 0, 255, 255]
    doc["layers"] = [layer for layer in doc["layers"] if layer["name"] == "face"]
    scene = inkwarp.Scene.from_dict(doc, base_dir=EXAMPLE)

    def open_pixels(time):
        frame = scene.render(time=time)[:200]  # above the mouth, which opens in a smile
        hole = np.all(frame[..., :3] == [255, 0, 255], axis=-1)
        return int(hole[:, :240].sum()), int(hole[:, 240:].sum())

    left, right = open_pixels(0.0)
    assert left > 2000 and right > 1000
    assert open_pixels(1.05) == (0, 0)


@pytest.mark.parametrize("source_has, target_has, expect", [
    (None, 1.0, 3.5 + 1 / 12),  # the source's last key (its length) outlasts the target's duration
    (4.0, None, 4.0),
    (4.0, 5.0, 5.0),
    (None, None, None),  # neither says: the result ends at its last key too
])
def test_the_result_lasts_as_long_as_the_longer_scene(source_has, target_has, expect):
    # A source with no duration of its own was cut to the target's shorter one, silently.
    source = face_scene()
    source["features"][0]["keys"].append({"t": 3.5, "points": [[60, 56]]})
    target = retraced(source, lambda p: 1.1 * p)
    for doc, has in ((source, source_has), (target, target_has)):
        doc.pop("duration", None)
        if has is not None:
            doc["duration"] = has
    result = inkwarp.transfer_dict(source, target)
    assert result.get("duration") == (pytest.approx(expect) if expect is not None else None)


def test_a_feature_traced_the_other_way_round_is_a_warning_naming_it():
    source = face_scene()
    target = retraced(source, lambda p: 1.1 * p)
    target["features"][2]["rest"].reverse()  # the brow, end to start
    with pytest.warns(inkwarp.InkwarpWarning, match=r'folds over near .* by feature "brow"'):
        inkwarp.transfer_dict(source, target)


def test_the_example_drawing_once_folded_the_map(tmp_path):
    # The cat's left brow as it was first traced (outer end first, the face's inner end
    # first) is caught.
    face, cat = _example_docs()
    for f in cat["features"]:
        if f["id"] == "brow_l":
            f["rest"].reverse()
    with pytest.warns(inkwarp.InkwarpWarning, match='by feature "brow_l"'):
        inkwarp.transfer_dict(face, cat)


def test_cli_prints_the_fold_warning_on_one_line_and_writes_the_scene(tmp_path, capsys):
    source = face_scene()
    target = retraced(source, lambda p: p)
    target["features"][2]["rest"].reverse()
    (tmp_path / "s.json").write_text(json.dumps(source))
    (tmp_path / "t.json").write_text(json.dumps(target))
    code = main(["transfer", "--source", str(tmp_path / "s.json"), "--target", str(tmp_path / "t.json"),
                 "-o", str(tmp_path / "o.json"), "--quiet"])
    assert code == 0 and (tmp_path / "o.json").exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith('inkwarp transfer: warning: ') and '"brow"' in err


@pytest.mark.parametrize("case", ["magnified past the limit", "target at one place"])
def test_a_transfer_that_cannot_make_a_scene_is_refused_not_written(tmp_path, capsys, case):
    # A target drawn 2000 times larger than its source magnified a 900 px move to 1.8e6 px:
    # the scene was written (exit 0) and then refused by validate and render. A target whose
    # matched points all lie at one place sent every move there, with a warning about
    # features traced the other way round.
    source = face_scene()
    source["features"][0]["keys"] = [{"t": 1.0, "points": [[960, 50]]}]
    if case == "magnified past the limit":
        target = retraced(source, lambda p: p * 2000.0)
        expect = "the key of 'nose' at t = 1 s maps to (1.92e+06, 100000) on the target (features[0].keys[0])"
    else:
        source["features"].pop()  # (a cut of zero length would be refused first)
        target = retraced(source, lambda p: np.array([40.0, 30.0]))
        expect = "every control point of the target's matched features lies at (40, 30)"
    target["width"] = target["height"] = 256
    (tmp_path / "s.json").write_text(json.dumps(source))
    (tmp_path / "t.json").write_text(json.dumps(target))
    code = main(["transfer", "--source", str(tmp_path / "s.json"), "--target", str(tmp_path / "t.json"),
                 "-o", str(tmp_path / "o.json")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and expect in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json", "t.json"]
