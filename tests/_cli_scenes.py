"""Small scenes for the command-line tests, written into a test's temporary directory."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

WIDTH, HEIGHT = 48, 40
SQUARE = (10, 18, 14, 22)  # x0, x1, y0, y1 of the dark square (exclusive ends)
SHIFT_PX = 8.0  # how far the square has moved at t = 1 s
FPS, DURATION = 4, 1.0  # 4 frames: t = 0, 0.25, 0.5, 0.75; the square at x0 + 2 * i


def square_picture() -> np.ndarray:
    """A dark square on a transparent picture (its alpha is its continuity matte)."""
    rgba = np.zeros((HEIGHT, WIDTH, 4), np.uint8)
    x0, x1, y0, y1 = SQUARE
    rgba[y0:y1, x0:x1] = (20, 30, 200, 255)
    return rgba


def square_doc() -> dict[str, Any]:
    """One layer, one point in the square moving right by SHIFT_PX over one second
    (linearly): a piece with one constrained node translates, so frame i shows the square
    moved by exactly SHIFT_PX * i / FPS pixels."""
    cx, cy = (SQUARE[0] + SQUARE[1] - 1) / 2, (SQUARE[2] + SQUARE[3] - 1) / 2
    return {
        "inkwarp": 1, "width": WIDTH, "height": HEIGHT, "fps": FPS, "duration": DURATION,
        "background": [255, 255, 255, 255],
        "layers": [{"name": "square", "image": "square.png"}],
        "features": [
            {"id": "grip", "kind": "point", "rest": [[cx, cy]],
             "keys": [{"t": 0.0, "points": [[cx, cy]], "interpolation": "linear"},
                      {"t": 1.0, "points": [[cx + SHIFT_PX, cy]]}]},
        ],
    }


def write_scene(directory: Path, doc: dict[str, Any] | None = None,
                name: str = "scene.json") -> Path:
    """Write ``square.png`` and the scene (``square_doc()`` unless given) into directory."""
    directory.mkdir(parents=True, exist_ok=True)
    Image.fromarray(square_picture(), "RGBA").save(directory / "square.png")
    path = directory / name
    text = doc if isinstance(doc, str) else json.dumps(
        square_doc() if doc is None else doc, indent=1)
    path.write_text(text)
    return path


def mutated(change) -> dict[str, Any]:
    """square_doc() with ``change(doc)`` applied to a copy."""
    doc = copy.deepcopy(square_doc())
    change(doc)
    return doc


def dark_columns(frame: np.ndarray) -> tuple[float, float]:
    """(centroid x, centroid y) of the dark pixels (the square) in an RGB(A) frame."""
    rgb = np.asarray(frame)[..., :3].astype(float)
    darkness = np.clip(255.0 - rgb.mean(axis=2), 0, None)
    darkness[darkness < 60] = 0
    ys, xs = np.mgrid[0:rgb.shape[0], 0:rgb.shape[1]]
    total = darkness.sum()
    return float((xs * darkness).sum() / total), float((ys * darkness).sum() / total)


def square_centroid_at(frame_index: int) -> tuple[float, float]:
    x0, x1, y0, y1 = SQUARE
    return ((x0 + x1 - 1) / 2 + SHIFT_PX * frame_index / FPS, (y0 + y1 - 1) / 2)


def leftovers(directory: Path) -> list[str]:
    """Names of temporary files a writer could have left in ``directory``."""
    return sorted(p.name for p in directory.iterdir() if ".part" in p.name)


def read_mp4(path: Path, width: int, height: int) -> tuple[list[np.ndarray], str]:
    """(RGB frames, ffmpeg's description of the streams) of a video, through the ffmpeg
    that imageio-ffmpeg ships (its own reader leaves a pipe open)."""
    import subprocess

    import imageio_ffmpeg

    done = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path), "-f", "rawvideo",
         "-pix_fmt", "rgb24", "-"], capture_output=True, check=True)
    size = width * height * 3
    data = done.stdout
    frames = [np.frombuffer(data[i:i + size], np.uint8).reshape(height, width, 3)
              for i in range(0, len(data), size)]
    return frames, done.stderr.decode("utf-8", "replace")
