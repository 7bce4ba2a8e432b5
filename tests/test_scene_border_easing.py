"""A layer's held border (``"border": "hold"``) and the eased key interpolations
(``ease-in``, ``ease-out``, ``ease-in-out``), through the Python API and the command line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import inkwarp

W, H = 64, 48


def _pull_scene(border: str | None, grid_step: int = 1) -> dict:
    """A blank layer whose drawing pulls hard: a vertical stroke near the top-left corner
    dragged 14 px up and left, towards the frame's edges."""
    layer: dict = {"name": "main"}
    if border is not None:
        layer["border"] = border
    rest = [[12.0, 8.0], [12.0, 30.0]]
    return {
        "inkwarp": 1, "width": W, "height": H, "fps": 10, "duration": 1.0,
        "solver": {"grid_step": grid_step, "tolerance": 0.01},
        "layers": [layer],
        "features": [{"id": "stroke", "kind": "polyline", "rest": rest,
                      "keys": [{"t": 0, "points": rest, "interpolation": "linear"},
                               {"t": 1, "points": [[2.0, 2.0], [2.0, 24.0]]}]}],
    }


def _edge(field: np.ndarray) -> np.ndarray:
    """The displacement lengths along the layer's outer edge."""
    length = np.hypot(field[..., 0], field[..., 1])
    return np.concatenate([length[0, :], length[-1, :], length[:, 0], length[:, -1]])


@pytest.mark.parametrize("grid_step", [1, 2])
def test_a_held_border_stays_within_half_a_pixel(grid_step):
    free = inkwarp.Scene.from_dict(_pull_scene(None, grid_step)).field(time=1.0)
    held = inkwarp.Scene.from_dict(_pull_scene("hold", grid_step)).field(time=1.0)
    # without the hold the pull drags the edge along: this frame pulls hard
    assert _edge(free).max() > 5.0
    assert _edge(held).max() <= 0.5
    # and the drawing is still followed: the stroke's middle moves by (-10, -6)
    np.testing.assert_allclose(held[19, 12], [-10.0, -6.0], atol=0.05)


def test_border_free_is_the_default_and_is_not_written_back():
    data = _pull_scene("free")
    scene = inkwarp.Scene.from_dict(data)
    assert "border" not in scene.to_dict()["layers"][0]
    np.testing.assert_array_equal(scene.field(time=1.0), inkwarp.Scene.from_dict(_pull_scene(None)).field(time=1.0))
    held = inkwarp.Scene.from_dict(_pull_scene("hold"))
    assert held.to_dict()["layers"][0]["border"] == "hold"


@pytest.mark.parametrize("method", ["triangulation", "beier-neely", "tps-exact"])
def test_every_method_holds_the_border(method):
    data = _pull_scene("hold")
    field = inkwarp.Scene.from_dict(data).field(time=1.0, method=method)
    assert _edge(field).max() <= 0.5


def test_a_bad_border_names_the_place_and_the_choices():
    data = _pull_scene("fixed")
    with pytest.raises(inkwarp.SceneError) as err:
        inkwarp.Scene.from_dict(data)
    text = str(err.value)
    assert "layers[0].border" in text and "hold" in text and "free" in text


CURVES = {
    "linear": lambda u: u,
    "ease-in": lambda u: u * u,
    "ease-out": lambda u: 1 - (1 - u) ** 2,
    "ease-in-out": lambda u: 3 * u * u - 2 * u ** 3,
}


def _dot_scene(interpolation: str) -> dict:
    return {
        "inkwarp": 1, "width": 40, "height": 20, "fps": 10, "duration": 1.0,
        "layers": [{"name": "main"}],
        "features": [{"id": "dot", "kind": "point", "rest": [[10, 10]],
                      "keys": [{"t": 0, "points": [[10, 10]], "interpolation": interpolation},
                               {"t": 1, "points": [[18, 10]]}]}],
    }


@pytest.mark.parametrize("interpolation", sorted(CURVES))
def test_eased_keys_follow_their_curves(interpolation):
    scene = inkwarp.Scene.from_dict(_dot_scene(interpolation))
    for u in (0.2, 0.5, 0.7):
        dx = scene.field(time=u)[10, 10, 0]
        assert dx == pytest.approx(8 * CURVES[interpolation](u), abs=0.02), (interpolation, u)


def test_eased_keys_round_trip_and_ease_in_starts_slower_than_ease_out():
    scene = inkwarp.Scene.from_dict(_dot_scene("ease-in"))
    assert scene.to_dict()["features"][0]["keys"][0]["interpolation"] == "ease-in"
    slow = scene.field(time=0.3)[10, 10, 0]
    fast = inkwarp.Scene.from_dict(_dot_scene("ease-out")).field(time=0.3)[10, 10, 0]
    assert slow < 1.0 < 4.0 < fast


def test_a_bad_interpolation_lists_the_easings():
    data = _dot_scene("ease")
    with pytest.raises(inkwarp.SceneError) as err:
        inkwarp.Scene.from_dict(data)
    text = str(err.value)
    assert "features[0].keys[0].interpolation" in text and "ease-in-out" in text


def test_the_command_line_honours_border_and_easing(tmp_path):
    data = _pull_scene("hold")
    data["features"][0]["keys"][0]["interpolation"] = "ease-in"
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(data))
    out = tmp_path / "field.npy"
    run = subprocess.run([sys.executable, "-m", "inkwarp.cli", "field", str(scene), "--time", "0.5", "-o", str(out), "-q"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    field = np.load(out)
    assert _edge(field).max() <= 0.5
    # ease-in: a quarter of the way at half the time
    np.testing.assert_allclose(field[19, 12], [-2.5, -1.5], atol=0.05)
    frames = tmp_path / "frames"
    run = subprocess.run([sys.executable, "-m", "inkwarp.cli", "render", str(scene), "-o", f"{frames}/", "-q"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert len(list(frames.glob("*.png"))) == 10
