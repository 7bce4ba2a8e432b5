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
