"""Draw the checkerboard and its mattes, then write both scenes:
``python examples/checkerboard-hole/make_art.py``.

The paper's "closing a gap in a checkerboard" (Litwinowicz & Williams, the colour plate of
interpolating surfaces): a checkerboard square with a vertical gap in it. Six control
points on the gap's right edge (red) are pulled left until the gap closes; two points at
the gap's ends (blue) and the four edges of the square are held.

- ``with-hole.json``: the continuity matte ``matte-hole.png`` has the gap, so the surface
  is torn there: the right edge moves and the left edge stays where it is.
- ``without-hole.json``: the matte ``matte-solid.png`` has no gap (the gap is only
  transparent, as in the paper's Beier-Neely plate), so the surface is one sheet: as the
  right edge is pulled across, the left edge is pushed along and folds under.

``setup.png`` shows the drawing over the picture (yellow arrows: where the red points go)
beside the matte with the hole, as the paper's first plate does.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

HERE = Path(__file__).resolve().parent
SIZE = 256
SQUARE = (32, 224)  # the checkerboard covers [32, 224) in x and y: 8 x 8 cells of 24 px
CELL = 24
GAP_X = (116, 140)  # the gap: columns 116..139, one cell wide
GAP_Y = (80, 176)  # rows 80..175
FPS = 24
DURATION = 2.0
CLOSE_AT = 1.5  # seconds: the gap is shut from here on

# On the gap's right edge (column 140), pulled 24 px left onto column 116: the gap shuts.
RED = np.array([[GAP_X[1], 95.5 + 13 * i] for i in range(6)], float)
RED_TO = RED - [GAP_X[1] - GAP_X[0], 0]
BLUE = np.array([[(GAP_X[0] + GAP_X[1]) / 2, GAP_Y[0] - 14],
                 [(GAP_X[0] + GAP_X[1]) / 2, GAP_Y[1] + 13]], float)
LO, HI = SQUARE[0], SQUARE[1] - 1
EDGES = {
    "edge_top": [[LO, LO], [HI, LO]],
    "edge_right": [[HI, LO], [HI, HI]],
    "edge_bottom": [[HI, HI], [LO, HI]],
    "edge_left": [[LO, HI], [LO, LO]],
}


def checkerboard() -> np.ndarray:
    y, x = np.mgrid[0:SIZE, 0:SIZE]
    inside = (x >= SQUARE[0]) & (x < SQUARE[1]) & (y >= SQUARE[0]) & (y < SQUARE[1])
    dark = ((x - SQUARE[0]) // CELL + (y - SQUARE[0]) // CELL) % 2 == 0
    rgba = np.zeros((SIZE, SIZE, 4), np.uint8)
    rgba[inside & dark] = (34, 58, 94, 255)
    rgba[inside & ~dark] = (246, 238, 214, 255)
    rgba[gap_mask()] = 0
    return rgba


def gap_mask() -> np.ndarray:
    mask = np.zeros((SIZE, SIZE), bool)
    mask[GAP_Y[0]:GAP_Y[1], GAP_X[0]:GAP_X[1]] = True
    return mask


def mattes() -> tuple[np.ndarray, np.ndarray]:
    """(with the gap, without it): white = connected surface."""
    square = np.zeros((SIZE, SIZE), np.uint8)
    square[SQUARE[0]:SQUARE[1], SQUARE[0]:SQUARE[1]] = 255
    hole = square.copy()
    hole[gap_mask()] = 0
    return hole, square


def scene(continuity: str) -> dict:
    features = []
    for i, (start, end) in enumerate(zip(RED, RED_TO)):
        features.append({"id": f"pull_{i}", "kind": "point", "rest": [_pt(start)],
                         "keys": [{"t": 0.0, "points": [_pt(start)]},
                                  {"t": CLOSE_AT, "points": [_pt(end)]}]})
    for i, p in enumerate(BLUE):
        features.append({"id": f"hold_{i}", "kind": "point", "rest": [_pt(p)]})
    for fid, pts in EDGES.items():
        features.append({"id": fid, "kind": "polyline", "rest": pts})
    return {
        "inkwarp": 1, "width": SIZE, "height": SIZE, "fps": FPS, "duration": DURATION,
        "background": [200, 200, 200, 255],
        "layers": [{"name": "board", "image": "checkerboard.png", "continuity": continuity}],
        "features": features,
    }


def _pt(p) -> list[float]:
    return [round(float(p[0]), 2), round(float(p[1]), 2)]


def setup_picture(board: np.ndarray, hole: np.ndarray) -> Image.Image:
    """The drawing over the picture, and the matte, side by side (3x)."""
    s = 3
    bg = Image.new("RGBA", (SIZE, SIZE), (200, 200, 200, 255))
    bg.alpha_composite(Image.fromarray(board))
    left = bg.resize((SIZE * s, SIZE * s), Image.NEAREST)
    d = ImageDraw.Draw(left)
    c = lambda p: (p[0] * s + s / 2, p[1] * s + s / 2)  # noqa: E731 - pixel centre, scaled
    for pts in EDGES.values():
        d.line([c(p) for p in pts], fill=(40, 110, 230, 255), width=4)
    for a, b in zip(RED, RED_TO):
        d.line([c(a), c(b)], fill=(250, 200, 0, 255), width=4)
        tip = c(b)
        d.polygon([tip, (tip[0] + 12, tip[1] - 7), (tip[0] + 12, tip[1] + 7)],
                  fill=(250, 200, 0, 255))
        r = 6
        d.ellipse([c(a)[0] - r, c(a)[1] - r, c(a)[0] + r, c(a)[1] + r], fill=(220, 30, 30, 255),
                  outline=(0, 0, 0, 255))
    for p in BLUE:
        r = 6
        d.ellipse([c(p)[0] - r, c(p)[1] - r, c(p)[0] + r, c(p)[1] + r],
                  fill=(40, 110, 230, 255), outline=(0, 0, 0, 255))
    right = Image.fromarray(hole).convert("RGBA").resize((SIZE * s, SIZE * s), Image.NEAREST)
    sheet = Image.new("RGBA", (SIZE * s * 2 + 12, SIZE * s), (255, 255, 255, 255))
    sheet.paste(left, (0, 0))
    sheet.paste(right, (SIZE * s + 12, 0))
    return sheet


def main():
    board = checkerboard()
    hole, solid = mattes()
    Image.fromarray(board).save(HERE / "checkerboard.png", optimize=True)
    Image.fromarray(hole).save(HERE / "matte-hole.png", optimize=True)
    Image.fromarray(solid).save(HERE / "matte-solid.png", optimize=True)
    setup_picture(board, hole).convert("RGB").save(HERE / "setup.png", optimize=True)
    (HERE / "with-hole.json").write_text(json.dumps(scene("matte-hole.png"), indent=1) + "\n")
    (HERE / "without-hole.json").write_text(
        json.dumps(scene("matte-solid.png"), indent=1) + "\n")
    for name in ("checkerboard.png", "matte-hole.png", "matte-solid.png", "setup.png",
                 "with-hole.json", "without-hole.json"):
        print(HERE / name)


if __name__ == "__main__":
    main()
