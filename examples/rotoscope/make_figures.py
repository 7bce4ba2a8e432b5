"""The rotoscoping guide's pictures (docs/guides/images/rotoscope-*.png).

    python examples/rotoscope/make_figures.py OUT_DIR

OUT_DIR holds ``make demo``'s ``actor-tracked.json`` and ``rotoscope.json`` (or run
``inkwarp track`` and ``inkwarp transfer`` as the guide does).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

HERE = Path(__file__).resolve().parent
DOCS = HERE.parents[1] / "docs" / "guides" / "images"
FRAMES = (0, 24, 31, 52)


def curve(feature: dict, points: np.ndarray) -> np.ndarray:
    """The feature's curve through ``points``, sampled every pixel (closed ones closed)."""
    import inkwarp

    closed = bool(feature.get("closed"))
    samples, moves = inkwarp.sample(feature["kind"], points, points, closed=closed)
    out = samples + moves
    return np.vstack([out, out[:1]]) if closed else out


def overlay(picture: np.ndarray, doc: dict, k: int | None, truth: dict | None = None) -> Image.Image:
    """The picture with the drawing at frame k (rest when None), 2x for legibility."""
    im = Image.fromarray(picture[..., :3]).resize((picture.shape[1] * 2, picture.shape[0] * 2))
    draw = ImageDraw.Draw(im)
    for f in doc["features"]:
        if truth is not None:
            q = curve(f, np.asarray(truth[f["id"]][k])) * 2
            draw.line([tuple(p) for p in q], fill=(60, 220, 60), width=3)
        pts = np.asarray(f["rest"] if k is None else f["keys"][k]["points"])
        draw.line([tuple(p) for p in curve(f, pts) * 2], fill=(235, 40, 40), width=2)
        pts = pts * 2
        for x, y in pts:
            draw.ellipse([x - 3, y - 3, x + 3, y + 3], fill=(235, 40, 40))
    draw.text((8, 8), "rest" if k is None else f"frame {k}", fill=(255, 255, 0))
    return im


def main(out_dir: str) -> None:
    import inkwarp

    out = Path(out_dir)
    DOCS.mkdir(parents=True, exist_ok=True)
    actor = json.loads((HERE / "actor.json").read_text())
    tracked = json.loads((out / "actor-tracked.json").read_text())
    truth = json.loads((HERE / "truth.json").read_text())["features"]
    from inkwarp.track import read_frame

    frames = {k: read_frame(HERE / "actor.mp4", k) for k in FRAMES}
    overlay(frames[0], actor, None).save(DOCS / "rotoscope-drawing.png")
    row = [overlay(frames[k], tracked, k, truth).resize((320, 320)) for k in FRAMES[1:]]
    sheet = Image.new("RGB", (320 * len(row), 320))
    for i, tile in enumerate(row):
        sheet.paste(tile, (320 * i, 0))
    sheet.save(DOCS / "rotoscope-tracked.png")
    actor_scene = inkwarp.Scene.load(HERE / "actor-scene.json")
    cat = inkwarp.Scene.load(out / "rotoscope.json")
    tiles = []
    for k in FRAMES:
        a = Image.fromarray(actor_scene.render(frame=k)).convert("RGB").resize((200, 200))
        c = Image.fromarray(cat.render(frame=k)).convert("RGB")
        c = c.resize((int(c.width * 200 / c.height), 200))
        tile = Image.new("RGB", (a.width + c.width, 200))
        tile.paste(a, (0, 0))
        tile.paste(c, (a.width, 0))
        tiles.append(tile)
    sheet = Image.new("RGB", (tiles[0].width * 2, 400))
    for i, tile in enumerate(tiles):
        sheet.paste(tile, ((i % 2) * tile.width, (i // 2) * 200))
    sheet.save(DOCS / "rotoscope-cat.png")
    print(f"wrote {DOCS}/rotoscope-drawing.png, rotoscope-tracked.png, rotoscope-cat.png")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out")
