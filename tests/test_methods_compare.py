"""The paper's "closing a gap in a checkerboard" plates, as numbers.

A checkerboard square with a slot (the gap) cut out of its continuity matte; six points
right of the gap are pulled left to close it, three points left of it and the square's
edges are held. With the hole, the thin plate leaves the gap's left edge nearly where it was;
without it (and with Beier–Neely, which knows no holes) the left edge is dragged along.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import inkwarp

SIZE = 96
SQUARE = (16, 79)  # first and last pixel of the square, both axes
GAP_X = (44, 51)  # the slot's columns
GAP_Y = (20, 75)  # the slot's rows: it nearly splits the square
PULL = -8.0  # how far the six points move (x)


def _png(path, array):
    Image.fromarray(array).save(path)
    return path.name


def checkerboard_scene(tmp_path, *, hole: bool, method: str = "tps"):
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    inside = (xs >= SQUARE[0]) & (xs <= SQUARE[1]) & (ys >= SQUARE[0]) & (ys <= SQUARE[1])
    gap = (xs >= GAP_X[0]) & (xs <= GAP_X[1]) & (ys >= GAP_Y[0]) & (ys <= GAP_Y[1])
    dark = ((xs // 8) + (ys // 8)) % 2 == 0
    rgba = np.zeros((SIZE, SIZE, 4), np.uint8)
    rgba[..., :3] = np.where(dark[..., None], 40, 230)
    rgba[..., 3] = np.where(inside & ~gap, 255, 0)
    layer = {"name": "board", "image": _png(tmp_path / "board.png", rgba)}
    if not hole:
        # Continuity everywhere: the surface is whole across the gap (the gap is still
        # transparent in the picture).
        layer["continuity"] = _png(tmp_path / "whole.png", np.full((SIZE, SIZE), 255, np.uint8))
    lo, hi = SQUARE
    pulled = [[x, y] for x in (54, 60) for y in (36, 47, 58)]
    features = [
        {"id": "edges", "kind": "polyline", "closed": True, "rest": [[lo, lo], [hi, lo], [hi, hi], [lo, hi]]},
    ] + [
        {"id": f"held_{i}", "kind": "point", "rest": [[30, y]]} for i, y in enumerate((36, 47, 58))
    ] + [
        {"id": f"pull_{i}", "kind": "point", "rest": [p], "keys": [{"t": 1.0, "points": [[p[0] + PULL, p[1]]]}]}
        for i, p in enumerate(pulled)
    ]
    doc = {
        "inkwarp": 1, "width": SIZE, "height": SIZE, "fps": 4, "duration": 1.0,
        "solver": {"method": method}, "layers": [layer], "features": features,
    }
    path = tmp_path / ("with_hole.json" if hole else "without_hole.json")
    path.write_text(json.dumps(doc))
    return path


def left_edge_motion(field):
    """Mean |Δx| along the gap's left edge (the column just left of the slot)."""
    x = GAP_X[0] - 1
    return float(np.abs(field[GAP_Y[0]:GAP_Y[1] + 1, x, 0]).mean())


@pytest.fixture(scope="module")
def comparisons(tmp_path_factory):
    out = {}
    for hole in (True, False):
        d = tmp_path_factory.mktemp("hole" if hole else "whole")
        out[hole] = inkwarp.compare(checkerboard_scene(d, hole=hole), 1.0)
    return out


def test_with_the_hole_the_left_edge_stays(comparisons):
    with_hole = left_edge_motion(comparisons[True].fields["tps"])
    without = left_edge_motion(comparisons[False].fields["tps"])
    assert without > 1.0, f"without the hole the left edge should be dragged ({without:.2f} px)"
    assert with_hole < 0.2 * without, f"{with_hole:.2f} px with the hole vs {without:.2f} px without"


def test_beier_neely_knows_no_holes_and_moves_the_left_edge(comparisons):
    for hole in (True, False):
        moved = left_edge_motion(comparisons[hole].fields["beier-neely"])
        assert moved > 1.0, f"Beier–Neely moved the left edge only {moved:.2f} px"
    # It is the same field either way: the matte plays no part.
    np.testing.assert_array_equal(comparisons[True].fields["beier-neely"], comparisons[False].fields["beier-neely"])


def test_every_method_meets_the_pulled_points(comparisons):
    for method in ("tps", "tps-exact", "triangulation"):
        field = comparisons[True].fields[method]
        for x in (54, 60):
            for y in (36, 47, 58):
                assert field[y, x, 0] == pytest.approx(PULL, abs=0.1), (method, x, y)
                assert field[y, x, 1] == pytest.approx(0.0, abs=0.1), (method, x, y)


def test_held_edges_stay(comparisons):
    lo, hi = SQUARE
    for method in ("tps", "tps-exact", "triangulation"):
        field = comparisons[True].fields[method]
        border = np.concatenate([field[lo, lo:hi + 1], field[hi, lo:hi + 1], field[lo:hi + 1, lo], field[lo:hi + 1, hi]])
        assert np.abs(border).max() < 0.1, method


def test_frames_and_fields_have_the_scene_shape(comparisons):
    c = comparisons[True]
    assert c.methods == list(inkwarp.METHODS)
    for m in c.methods:
        assert c.frames[m].shape == (SIZE, SIZE, 4) and c.frames[m].dtype == np.uint8
        assert c.fields[m].shape == (SIZE, SIZE, 2) and c.fields[m].dtype == np.float32


def test_the_sheet_is_written(comparisons, tmp_path):
    out = tmp_path / "sheet.png"
    inkwarp.comparison_sheet(comparisons[True], out)
    with Image.open(out) as im:
        assert im.size[0] > 300 and im.size[1] > 4 * 200


def test_cli_compare(tmp_path, capsys):
    from inkwarp.cli import main

    scene = checkerboard_scene(tmp_path, hole=True)
    out = tmp_path / "sheet.png"
    assert main(["compare", str(scene), "--time", "1", "--methods", "tps,triangulation", "-o", str(out)]) == 0
    assert out.exists()
    assert main(["compare", str(scene), "--methods", "bicubic", "-o", str(out)]) == 2
    assert 'unknown method "bicubic"' in capsys.readouterr().err
    assert main(["compare", str(scene), "--time", "1e300", "-o", str(out)]) == 2
    assert "--time 1e+300: give a time in seconds from -100000 to 100000" in capsys.readouterr().err
    assert main(["compare", str(scene), "--time", "-0.5", "-o", str(out)]) == 0  # before the keys


EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "checkerboard-hole"
EXAMPLE_GAP = (slice(80, 176), 115)  # rows of the gap, the column just left of it


def example_left_edge(name, method):
    field = inkwarp.Scene.load(EXAMPLES / name).field(time=2.0, method=method)
    return float(np.abs(field[EXAMPLE_GAP[0], EXAMPLE_GAP[1], 0]).mean())


def test_the_example_plates_as_numbers():
    with_hole = example_left_edge("with-hole.json", "tps")
    without = example_left_edge("without-hole.json", "tps")
    beier_neely = example_left_edge("with-hole.json", "beier-neely")
    assert with_hole < 0.2 * without, (with_hole, without)
    assert without > 5.0 and beier_neely > 5.0, (without, beier_neely)


def test_the_committed_plates_exist_and_the_page_shows_them():
    assert (EXAMPLES / "checkerboard-plates.png").is_file()
    page = (EXAMPLES.parents[1] / "docs" / "concepts" / "comparison.md").read_text()
    assert "examples/checkerboard-hole/checkerboard-plates.png" in page


# ---- method settings and notes through scenes ----------------------------------------------


def test_the_notes_of_each_method_reach_the_comparison(comparisons):
    notes = comparisons[True].notes
    assert notes["tps"] == []
    for method in ("tps-exact", "triangulation", "beier-neely"):
        assert notes[method] == [
            f"{method} ignores the continuity matte and cuts: its surface is continuous across holes."
        ]
    # Without the hole there is nothing to ignore.
    assert all(n == [] for n in comparisons[False].notes.values())


def test_a_field_at_rest_is_drawn_flat_not_as_its_rounding(comparisons):
    # Beier-Neely at rest gives about 1e-14 px: scaled to the panel, that rounding filled
    # it with full-contrast speckle under a "±0.0 px" heading.
    import dataclasses

    rest = dataclasses.replace(comparisons[True])
    noise = np.random.default_rng(0).normal(0, 1e-14, rest.fields[rest.methods[0]].shape).astype(np.float32)
    rest.fields = {m: noise for m in rest.methods}
    fig = inkwarp.comparison_sheet(rest)
    panel = fig.axes[1].get_images()[0].get_array()
    assert float(np.ptp(np.asarray(panel)[..., :3])) < 1 / 255, np.ptp(np.asarray(panel)[..., :3])  # one level at most
    assert fig.axes[1].get_title() == "ΔX surface (flat)" and not fig.axes[1].collections


def test_the_sheet_prints_the_notes_under_the_frames(comparisons):
    fig = inkwarp.comparison_sheet(comparisons[True])
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert sum("ignores the continuity matte" in text.replace("\n", " ") for text in texts) == 3


def test_long_notes_stay_clear_of_the_next_row_and_every_panel_has_one_size(comparisons):
    # Six lines of notes under a frame ran into the top of the next row's frame; a row with
    # notes drew its panels larger than one without (the sheet compares them side by side).
    import dataclasses

    base = comparisons[True]
    notes = {m: [f"layer \"layer {k}\": a remark about this interpolant long enough to wrap onto a second line"
                 for k in range(3)] if m != base.methods[1] else [] for m in base.methods}
    # Landscape frames, as a character's 320 × 256 picture.
    frames = {m: np.zeros((256, 320, 4), np.uint8) for m in base.methods}
    fields = {m: np.zeros((256, 320, 2), np.float32) for m in base.methods}
    fig = inkwarp.comparison_sheet(dataclasses.replace(base, notes=notes, frames=frames, fields=fields, drawing=[]))
    fig.canvas.draw()  # the layout is made when drawn
    renderer = fig.canvas.get_renderer()
    panels = [ax for ax in fig.axes if ax.images]
    sizes = {(round(ax.get_window_extent(renderer).width), round(ax.get_window_extent(renderer).height)) for ax in panels}
    assert len(panels) == 2 * len(base.methods) and len(sizes) == 1, sizes
    said = [t.get_window_extent(renderer) for ax in fig.axes for t in ax.texts]
    assert len(said) == len(base.methods) - 1
    for box in said:
        assert box.height > 0
        for panel in (ax.get_window_extent(renderer) for ax in panels):
            assert box.y0 >= panel.y1 or box.y1 <= panel.y0, (box, panel)


def test_a_thinning_note_and_the_cap_from_the_scene_file(tmp_path):
    path = checkerboard_scene(tmp_path, hole=False)
    doc = json.loads(path.read_text())
    doc["solver"]["tps_exact"] = {"max_samples": 40}
    path.write_text(json.dumps(doc))
    capped = inkwarp.compare(path, 1.0, "tps-exact")  # 4 × 63 edge samples and 9 points
    assert capped.notes["tps-exact"] == [
        "tps-exact thinned 261 distinct sample positions to 40 by farthest-point sampling (max_samples)."
    ]
    # compare's keyword replaces the scene's cap.
    assert "to 25 " in inkwarp.compare(path, 1.0, "tps-exact", max_samples=25).notes["tps-exact"][0]
    assert inkwarp.compare(path, 1.0, "tps-exact", max_samples=5000).notes["tps-exact"] == []


def test_beier_neely_weights_from_the_scene_file_and_from_compare(tmp_path):
    path = checkerboard_scene(tmp_path, hole=True, method="beier-neely")
    default = inkwarp.Scene.load(path).field(time=1.0)
    doc = json.loads(path.read_text())
    doc["solver"]["beier_neely"] = {"a": 6.0, "b": 1.0, "p": 0.5}
    path.write_text(json.dumps(doc))
    weighted = inkwarp.Scene.load(path).field(time=1.0)
    assert np.abs(weighted - default).max() > 0.5
    # The scene's weights are the field inkwarp.interpolate gives with them; compare uses
    # them, and its keywords replace them (the others kept).
    compared = inkwarp.compare(path, 1.0, "beier-neely")
    np.testing.assert_array_equal(compared.fields["beier-neely"], weighted)
    back = inkwarp.compare(path, 1.0, "beier-neely", a=1.0, b=2.0, p=0.0)
    np.testing.assert_array_equal(back.fields["beier-neely"], default)
    only_a = inkwarp.compare(path, 1.0, "beier-neely", a=1.0)
    doc["solver"]["beier_neely"] = {"a": 1.0, "b": 1.0, "p": 0.5}
    path.write_text(json.dumps(doc))
    np.testing.assert_array_equal(only_a.fields["beier-neely"], inkwarp.Scene.load(path).field(time=1.0))


@pytest.mark.parametrize(
    "settings, path",
    [
        ({"beier_neely": {"a": 0}}, "solver.beier_neely.a"),
        ({"beier_neely": {"p": -1}}, "solver.beier_neely.p"),
        ({"beier_neely": {"alpha": 1}}, "solver.beier_neely.alpha"),
        ({"tps_exact": {"max_samples": 0}}, "solver.tps_exact.max_samples"),
    ],
)
def test_bad_method_settings_name_their_place(tmp_path, settings, path):
    scene = json.loads(checkerboard_scene(tmp_path, hole=True).read_text())
    scene["solver"].update(settings)
    problems = inkwarp.validate_scene(scene, base_dir=tmp_path)
    assert [p for p, _ in problems] == [path]
    with pytest.raises(inkwarp.SceneError) as err:
        inkwarp.Scene.from_dict(scene, base_dir=tmp_path)
    assert err.value.path == path


def test_bad_settings_for_compare_are_scene_errors(tmp_path):
    path = checkerboard_scene(tmp_path, hole=True)
    with pytest.raises(inkwarp.SceneError, match=r"solver\.beier_neely\.b: .*from 0 to 16") as err:
        inkwarp.compare(path, 1.0, "beier-neely", b=-2)
    assert err.value.path == "solver.beier_neely.b"
    with pytest.raises(inkwarp.SceneError, match="max_samples"):
        inkwarp.compare(path, 1.0, "tps-exact", max_samples=9000)
    with pytest.raises(ValueError, match="finite"):
        inkwarp.compare(path, 1.0, "beier-neely", a=float("nan"))


@pytest.mark.parametrize("time", [float("nan"), float("inf"), "1"])
def test_a_time_that_is_no_time_is_refused_by_name_and_none_is_the_scenes_end(tmp_path, time):
    # NaN and infinity were taken, and titled the sheet "t = nan s"; the default was 0, where
    # `inkwarp compare` shows the scene's end.
    path = checkerboard_scene(tmp_path, hole=True)
    with pytest.raises(ValueError, match=r"time \(seconds\)"):
        inkwarp.compare(path, time, "tps")
    assert inkwarp.compare(path, methods="tps").time == inkwarp.Scene.load(path).duration


@pytest.mark.parametrize("scene", [None, 5, {"inkwarp": 1}])
def test_a_scene_that_is_neither_a_scene_nor_a_path_is_a_value_error(tmp_path, scene):
    with pytest.raises(ValueError, match=r"the scene must be an inkwarp\.Scene or the path of a scene file; got"):
        inkwarp.compare(scene, 1.0)
    with pytest.raises(ValueError, match=r"the output must be a path .*; got NoneType"):
        inkwarp.render(checkerboard_scene(tmp_path, hole=True), None)


def test_the_schema_has_the_method_settings():
    solver = inkwarp.scene_schema()["$defs"]["SolverDoc"]["properties"]
    assert solver["beier_neely"]["default"] == {"a": 1.0, "b": 2.0, "p": 0.0}
    assert solver["tps_exact"]["default"] == {"max_samples": 1000}


def test_cli_compare_takes_method_settings_and_prints_notes(tmp_path, capsys):
    from inkwarp.cli import main

    scene = checkerboard_scene(tmp_path, hole=True)
    out = tmp_path / "sheet.png"
    args = ["compare", str(scene), "--time", "1", "--methods", "tps-exact,beier-neely", "-o", str(out)]
    assert main(args + ["--beier-neely", "a=3,p=0.25", "--max-samples", "30"]) == 0
    printed = capsys.readouterr().out
    assert "tps-exact: tps-exact thinned" in printed and "to 30 by" in printed
    assert "beier-neely: beier-neely ignores the continuity matte" in printed
    assert main(args + ["--beier-neely", "a=0"]) == 2
    err = capsys.readouterr().err
    assert "--beier-neely a=0: Beier–Neely's a must be" in err and "solver." not in err, err
    # Every bad setting named by its option, none by the scene's solver.
    assert main(args + ["--beier-neely", "a=0,b=-1", "--max-samples", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("--beier-neely a=0,b=-1: ") == 2 and "--max-samples: " in err and "solver." not in err, err
    assert main(args + ["--beier-neely", "c=1"]) == 2
    assert "a=A,b=B,p=P" in capsys.readouterr().err


def test_compare_draws_the_top_layer_of_a_layered_scene():
    cat = inkwarp.Scene.load(Path(__file__).resolve().parents[1] / "examples" / "cat" / "scene.json")
    c = inkwarp.compare(cat, 0.95, "tps-exact")
    np.testing.assert_array_equal(c.fields["tps-exact"], cat.field(time=0.95, layer="face", method="tps-exact"))
    assert c.notes["tps-exact"][0].startswith('layer "face": tps-exact thinned')


def test_compare_says_a_tps_solve_that_did_not_converge(tmp_path):
    # `Scene.field` warned; `compare` returned the same unconverged field with no note.
    path = checkerboard_scene(tmp_path, hole=True)
    doc = json.loads(path.read_text())
    doc["solver"]["max_cycles"] = 1
    path.write_text(json.dumps(doc))
    with pytest.warns(inkwarp.ConvergenceWarning, match=r"at t = 1 s \(frame 4\)") as caught:
        compared = inkwarp.compare(path, 1.0, ["tps", "triangulation"])
    assert all(w.filename == __file__ for w in caught), [w.filename for w in caught]  # the caller's line
    stopped = [n for n in compared.notes["tps"] if "max_cycles" in n]
    assert len(stopped) == 1 and compared.notes["triangulation"] == [n for n in compared.notes["triangulation"] if "max_cycles" not in n]
    with pytest.warns(inkwarp.ConvergenceWarning):
        field = inkwarp.Scene.load(path).field(time=1.0)
    np.testing.assert_array_equal(compared.fields["tps"], field)
