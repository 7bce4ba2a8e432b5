"""Small scenes and pictures for the scene tests, made here so the tests need no files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

W, H = 40, 30


def gradient(width: int = W, height: int = H, hole: tuple[slice, slice] | None = None) -> np.ndarray:
    """An opaque RGBA gradient (red across, green down), transparent inside ``hole``."""
    y, x = np.mgrid[0:height, 0:width]
    image = np.zeros((height, width, 4), np.uint8)
    image[..., 0] = x * 255 // max(width - 1, 1)
    image[..., 1] = y * 255 // max(height - 1, 1)
    image[..., 2] = 90
    image[..., 3] = 255
    if hole is not None:
        image[hole] = 0
    return image


def two_layer_scene() -> dict[str, Any]:
    """A back layer and a front layer with a hole, a moving point, a spline and a cut."""
    return {
        "inkwarp": 1,
        "fps": 20,
        "duration": 2.0,
        "background": [0, 0, 0, 255],
        "layers": [
            {"name": "back", "image": "back.png"},
            {"name": "front", "image": "front.png", "features": ["dot", "brow", "slit"]},
        ],
        "features": [
            {"id": "dot", "kind": "point", "rest": [[10, 10]],
             "keys": [{"t": 0, "points": [[10, 10]]}, {"t": 1, "points": [[13, 11]]},
                      {"t": 2, "points": [[10, 10]], "interpolation": "linear"}]},
            {"id": "brow", "kind": "spline", "rest": [[20, 6], [26, 4], [32, 6]],
             "keys": [{"t": 0, "points": [[20, 6], [26, 4], [32, 6]]},
                      {"t": 1.5, "points": [[20, 6], [26, 1], [32, 6]]}]},
            {"id": "slit", "kind": "cut", "rest": [[5.5, 20.5], [20.5, 20.5]]},
        ],
    }


def write_scene(folder: Path, scene: dict[str, Any] | None = None, name: str = "scene.json") -> Path:
    """Writes the pictures and the scene into ``folder``; returns the scene file."""
    Image.fromarray(gradient()).save(folder / "back.png")
    Image.fromarray(gradient(hole=(slice(2, 8), slice(2, 8)))).save(folder / "front.png")
    path = folder / name
    path.write_text(json.dumps(two_layer_scene() if scene is None else scene))
    return path
