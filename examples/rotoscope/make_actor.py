"""Make the rotoscoping example's footage: an "actor" video whose motion is known.

The actor is scikit-image's bundled ``astronaut`` photograph (Eileen Collins, NASA; public
domain), cropped to her face. An inkwarp scene (``actor-scene.json``) animates it — a turn
of the head, a blink, a broader smile — and is rendered to ``actor.mp4``. The drawing that
drove it, without its keys, is ``actor.json``: what an animator would trace over the first
frame before running ``inkwarp track``. Its features have the ids, kinds and point counts
of ``examples/face`` (and of ``examples/transfer/cat-target.json``), so the tracked
performance transfers onto the cat. ``truth.json`` holds the drawing at every frame, to
measure the tracker by.

    python examples/rotoscope/make_actor.py
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SIZE = 320
FPS = 24
DURATION_S = 2.5

# Traced over the picture (x right, y down, pixels); ids and directions as examples/face.
HEAD = [[160 + 90 * math.sin(2 * math.pi * i / 12), 160 - 122 * math.cos(2 * math.pi * i / 12)]
        for i in range(12)]
REST = {
    "head": ("spline", HEAD, True),
    "nose": ("spline", [[158, 165], [152, 192], [172, 198]], False),
    "brow_l": ("spline", [[132, 117], [114, 113], [97, 119]], False),
    "brow_r": ("spline", [[190, 122], [210, 119], [232, 127]], False),
    "lid_l_upper": ("spline", [[99, 135.5], [107, 130], [116, 128.5], [126, 131], [134, 139]], False),
    "lid_l_lower": ("spline", [[99, 135.5], [107, 142], [116, 145], [126, 144], [134, 139]], False),
    "lid_r_upper": ("spline", [[182, 145.5], [191, 138], [202, 135.5], [213, 136.5], [222, 141]], False),
    "lid_r_lower": ("spline", [[182, 145.5], [191, 149.5], [202, 151], [213, 149.5], [222, 141]], False),
    "lip_upper": ("spline", [[119, 216], [139, 214], [160, 215], [180, 214], [200, 217]], False),
    "lip_lower": ("spline", [[119, 216], [139, 236], [160, 243], [181, 236], [200, 217]], False),
}
# Held still: the picture's edges (the paper's stationary lines along the edges).
BORDER = [[0, 0], [SIZE - 1, 0], [SIZE - 1, SIZE - 1], [0, SIZE - 1]]

# The performance: (time s, head turn px, blink 0..1, smile 0..1), linear in between.
BEATS = [(0.0, 0, 0, 0), (0.3, 0, 0, 0), (1.0, 7, 0, 0), (1.15, 7, 0, 0), (1.27, 7, 0.9, 0),
         (1.4, 7, 0, 0), (1.55, 7, 0, 0.1), (2.0, 2, 0, 1), (2.5, 0, 0, 1)]


def pose(turn_px: float, blink: float, smile: float) -> dict[str, np.ndarray]:
    out = {}
    for fid, (_, rest, _) in REST.items():
        p = np.array(rest, float)
        # A turn to her left: the middle of the face moves most, the outline's sides least.
        p[:, 0] += turn_px * np.clip(1 - ((p[:, 0] - 160) / 120) ** 2, 0, 1)
        p[:, 1] += 0.15 * turn_px * np.clip(1 - ((p[:, 0] - 160) / 120) ** 2, 0, 1)
        out[fid] = p
    for side in ("l", "r"):
        upper, lower = out[f"lid_{side}_upper"], out[f"lid_{side}_lower"]
        upper[1:-1] += blink * 0.85 * (lower[1:-1] - upper[1:-1])
    corners = np.array([[-4, -7], [4, -7]]) * smile
    for lip in ("lip_upper", "lip_lower"):
        out[lip][0] += corners[0]
        out[lip][-1] += corners[1]
        out[lip][1] += corners[0] * 0.5
        out[lip][3] += corners[1] * 0.5
    out["lip_lower"][1:4, 1] += 3 * smile
    out["brow_l"][:, 1] -= 3 * smile
    out["brow_r"][:, 1] -= 3 * smile
    return out


def truth_at(time_s: float) -> dict[str, np.ndarray]:
    times = [b[0] for b in BEATS]
    i = min(max(np.searchsorted(times, time_s, side="right") - 1, 0), len(BEATS) - 2)
    w = min(max((time_s - times[i]) / (times[i + 1] - times[i]), 0.0), 1.0)
    a, b = pose(*BEATS[i][1:]), pose(*BEATS[i + 1][1:])
    return {fid: a[fid] * (1 - w) + b[fid] * w for fid in a}


def feature(fid: str, keys: bool) -> dict:
    kind, rest, closed = REST[fid]
    out: dict = {"id": fid, "kind": kind, "rest": np.round(rest, 2).tolist()}
    if closed:
        out["closed"] = True
    if keys:
        out["keys"] = [{"t": t, "points": np.round(pose(*beat)[fid], 3).tolist(),
                        "interpolation": "linear"} for t, *beat in BEATS]
    return out


def scene(keys: bool) -> dict:
    doc = {"inkwarp": 1, "width": SIZE, "height": SIZE, "fps": FPS, "duration": DURATION_S,
           "background": [255, 255, 255, 255],
           "layers": [{"name": "actor", "image": "actor.png"}],
           "features": [feature(fid, keys) for fid in REST]}
    if keys:
        doc["features"].append({"id": "border", "kind": "polyline", "closed": True,
                                "rest": BORDER})
    return doc


def main() -> None:
    from PIL import Image
    from skimage import data

    import inkwarp
    from inkwarp.imaging import write_png
    from inkwarp.video import write_frames

    face = Image.fromarray(data.astronaut()).crop((144, 32, 304, 192))
    write_png(HERE / "actor.png", np.asarray(face.resize((SIZE, SIZE), Image.LANCZOS)))
    for name, doc in (("actor-scene.json", scene(True)), ("actor.json", scene(False))):
        (HERE / name).write_text(json.dumps(doc, indent=1) + "\n")
    frames = math.ceil(DURATION_S * FPS)
    truth = {fid: [np.round(truth_at(k / FPS)[fid], 3).tolist() for k in range(frames)]
             for fid in REST}
    (HERE / "truth.json").write_text(json.dumps({"fps": FPS, "features": truth}) + "\n")
    rendered = inkwarp.Scene.load(HERE / "actor-scene.json")
    write_frames(HERE / "actor.mp4", rendered.frames(), fps=FPS)
    print(f"wrote {HERE / 'actor.mp4'} ({frames} frames), actor.json, truth.json")


if __name__ == "__main__":
    main()
