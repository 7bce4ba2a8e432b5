"""Trace the face example's drawing over the cat photograph: ``cat-target.json``.

Animation transfer (DESIGN §7, the paper's actor-to-cat plate) needs the target drawing to
have the source's feature ids, kinds and control-point counts. This script traces every
feature of ``examples/face/scene.json`` over the cat (``examples/cat``'s pictures and
layers) — head outline, shoulders, nose, brows, lids, lips, eye sockets and pupils — plus
the cat's own extras that the face lacks (the picture's border held, the cut along the
mouth), which keep their own (no) keys. ``inkwarp transfer`` then maps the face's keys
onto it:

    python examples/transfer/make_target.py
    inkwarp transfer --source examples/face/scene.json \\
        --target examples/transfer/cat-target.json -o examples/transfer/cat-animated.json
    inkwarp render examples/transfer/cat-animated.json -o cat-animated.gif
"""

from __future__ import annotations

import json
import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
CAT = HERE.parent / "cat"


def ellipse(cx: float, cy: float, rx: float, ry: float, n: int, start_deg: float = -90.0) -> list[list[float]]:
    """``n`` points clockwise (y down) around an ellipse, the first at ``start_deg``."""
    out = []
    for i in range(n):
        a = math.radians(start_deg + 360.0 * i / n)
        out.append([round(cx + rx * math.cos(a), 1), round(cy + ry * math.sin(a), 1)])
    return out


def thin(points: list[list[float]], n: int) -> list[list[float]]:
    """``n`` of ``points``, evenly spread, the first and the last kept."""
    step = (len(points) - 1) / (n - 1)
    return [points[round(i * step)] for i in range(n)]


def drawing() -> list[dict]:
    cat = {f["id"]: f for f in json.loads((CAT / "scene.json").read_text())["features"]}
    # The cat's lids (traced along each eye's rim with 9 points), thinned to the face's 5:
    # matched features have the same number of control points.
    lids = {k: thin(cat[k]["rest"], 5) for k in ("lid_l_upper", "lid_l_lower", "lid_r_upper", "lid_r_lower")}
    spline = lambda id, rest, **kw: {"id": id, "kind": "spline", "rest": rest, **kw}  # noqa: E731
    return [
        # The face's features, traced on the cat (the face's left eye is the picture's left).
        spline("head", ellipse(240, 168, 172, 118, 12), closed=True),
        {"id": "shoulders", "kind": "polyline",
         "rest": [[24, 296], [60, 286], [150, 290], [330, 290], [400, 286], [440, 296]]},
        spline("nose", [[248, 226], [252, 244], [268, 246]]),
        spline("brow_l", [[140, 84], [170, 68], [208, 86]]),
        spline("brow_r", [[292, 114], [318, 92], [352, 100]]),
        *[spline(k, v) for k, v in lids.items()],
        spline("lip_upper", [[224, 273], [240, 268], [255, 266], [270, 268], [286, 273]]),
        spline("lip_lower", [[224, 273], [240, 279], [255, 281], [270, 279], [286, 273]]),
        {"id": "socket_l", "kind": "polyline", "closed": True, "rest": ellipse(171, 116, 42, 38, 8)},
        {"id": "socket_r", "kind": "polyline", "closed": True, "rest": ellipse(322, 135, 34, 34, 8)},
        {"id": "pupil_l", "kind": "point", "rest": [[172, 112]]},
        {"id": "pupil_r", "kind": "point", "rest": [[318, 134]]},
        # The cat's own: the border held, the mouth a cut (no keys; they stay as they are).
        cat["frame"], cat["frame_right"], cat["mouth"],
    ]


def scene() -> dict:
    cat_doc = json.loads((CAT / "scene.json").read_text())
    eyes = ["head", "shoulders", "socket_l", "socket_r", "pupil_l", "pupil_r", "frame", "frame_right"]
    return {
        "inkwarp": 1, "width": cat_doc["width"], "height": cat_doc["height"], "fps": 24, "duration": 2.5,
        "background": cat_doc.get("background", [0, 0, 0, 255]),
        "layers": [
            {"name": "mouth", "image": "../cat/mouth.png", "features": ["head", "shoulders", "frame", "frame_right"]},
            # The eyeballs behind the fur follow the head and their sockets; the pupils glance.
            {"name": "eyes", "image": "../cat/cat-eyes.png", "features": eyes},
            {"name": "face", "image": "../cat/cat-face.png",
             "features": [f["id"] for f in drawing() if f["id"] not in ("socket_l", "socket_r", "pupil_l", "pupil_r")]},
        ],
        "features": drawing(),
    }


if __name__ == "__main__":
    (HERE / "cat-target.json").write_text(json.dumps(scene(), indent=1) + "\n")
    print(HERE / "cat-target.json")
