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

The transfer map ``W`` is fitted from the face's rest control points to these, and every
key of the face goes through it, so the drawing has to correspond point for point:

- matched curves run the same way (both brows from the inner end to the outer one, as the
  face draws them; a reversed curve folds ``W`` over on itself, and the keys with it);
- the lids are 5-point tracings (the face's count) of the cat's 9-point lids, within
  0.75 px of them, so that they lie on the fur just outside the eye holes as the cat's do;
- the head outline is centred on the cat's face and runs below the picture, and the
  shoulders are below it too, so the chin keeps its place between the mouth and the head
  outline (a head outline just under the lips squeezes the face's chin onto a line);
- the eye sockets, which the photograph does not show (they only move the eyes behind the
  fur), are placed where the thin-plate map of the other features puts the face's.

``tests/test_methods_transfer.py`` checks that ``W`` keeps its orientation everywhere over
the face's head (no fold) and that the cat's eyes shut at the blink.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
CAT = HERE.parent / "cat"
FACE = HERE.parent / "face"

# The cat's lids (examples/cat traces each along an eye's rim with 9 points) as the face's
# 5 points: corner, three points that keep the curve within 0.75 px of the 9-point one,
# corner.
LIDS = {
    "lid_l_upper": [[135.0, 117.0], [141.0, 96.0], [165.0, 87.0], [193.0, 93.5], [205.0, 112.0]],
    "lid_l_lower": [[135.0, 117.0], [142.0, 135.0], [171.5, 148.0], [201.5, 134.5], [205.0, 112.0]],
    "lid_r_upper": [[297.0, 158.0], [296.0, 139.0], [311.5, 115.5], [340.5, 110.0], [346.0, 118.0]],
    "lid_r_lower": [[297.0, 158.0], [307.5, 164.5], [330.5, 158.0], [344.5, 140.5], [346.0, 118.0]],
}
# Placed by the map of the other features (see `sockets`), not traced.
PLACED = ("socket_l", "socket_r")


def ellipse(cx: float, cy: float, rx: float, ry: float, n: int, start_deg: float = -90.0) -> list[list[float]]:
    """``n`` points clockwise (y down) around an ellipse, the first at ``start_deg``."""
    out = []
    for i in range(n):
        a = math.radians(start_deg + 360.0 * i / n)
        out.append([round(cx + rx * math.cos(a), 1), round(cy + ry * math.sin(a), 1)])
    return out


def traced() -> list[dict]:
    """The features traced over the photograph (every face feature but the sockets), and
    the cat's own."""
    cat = {f["id"]: f for f in json.loads((CAT / "scene.json").read_text())["features"]}
    spline = lambda id, rest, **kw: {"id": id, "kind": "spline", "rest": rest, **kw}  # noqa: E731
    return [
        # The face's features, traced on the cat (the face's left eye is the picture's left).
        spline("head", ellipse(245, 165, 155, 140, 12), closed=True),
        {"id": "shoulders", "kind": "polyline",
         "rest": [[24, 336], [60, 326], [150, 330], [330, 330], [400, 326], [440, 336]]},
        spline("nose", [[248, 226], [252, 244], [268, 246]]),
        # Inner end first, as the face's brows run.
        spline("brow_l", [[208, 86], [170, 68], [140, 84]]),
        spline("brow_r", [[292, 114], [318, 92], [352, 100]]),
        *[spline(k, v) for k, v in LIDS.items()],
        spline("lip_upper", [[224, 273], [240, 268], [255, 266], [270, 268], [286, 273]]),
        spline("lip_lower", [[224, 273], [240, 279], [255, 281], [270, 279], [286, 273]]),
        {"id": "pupil_l", "kind": "point", "rest": [[172, 112]]},
        {"id": "pupil_r", "kind": "point", "rest": [[318, 134]]},
        # The cat's own: the picture's border held all round (no ear flicks here), the
        # mouth a cut. No keys; they stay as they are.
        {"id": "frame", "kind": "polyline", "rest": [[0.0, 299.0], [0.0, 0.0], [450.0, 0.0]]},
        {"id": "frame_right", "kind": "polyline", "rest": [[450.0, 0.0], [450.0, 299.0], [0.0, 299.0]]},
        cat["mouth"],
    ]


def sockets(features: list[dict]) -> list[dict]:
    """The face's eye sockets carried onto the cat by the thin-plate map fitted from the
    face's other features to ``features``."""
    import inkwarp

    face = {f["id"]: f for f in json.loads((FACE / "scene.json").read_text())["features"]}
    shared = [f for f in features if f["id"] in face and f["id"] not in PLACED]
    source = [p for f in shared for p in face[f["id"]]["rest"]]
    target = [p for f in shared for p in f["rest"]]
    w = inkwarp.ThinPlateMap(source, target)
    return [
        {"id": fid, "kind": "polyline", "closed": True,
         "rest": [[round(float(x), 1), round(float(y), 1)] for x, y in w(face[fid]["rest"])]}
        for fid in PLACED
    ]


def drawing() -> list[dict]:
    features = traced()
    placed = sockets(features)
    # The sockets go after the lips, where the face lists them.
    at = next(i for i, f in enumerate(features) if f["id"] == "pupil_l")
    return features[:at] + placed + features[at:]


def scene() -> dict:
    cat_doc = json.loads((CAT / "scene.json").read_text())
    eyes = ["head", "shoulders", "socket_l", "socket_r", "pupil_l", "pupil_r", "frame", "frame_right"]
    features = drawing()
    return {
        "inkwarp": 1, "width": cat_doc["width"], "height": cat_doc["height"], "fps": 24, "duration": 2.5,
        "background": cat_doc.get("background", [0, 0, 0, 255]),
        "layers": [
            {"name": "mouth", "image": "../cat/mouth.png", "features": ["head", "shoulders", "frame", "frame_right"]},
            # The eyeballs behind the fur follow the head and their sockets; the pupils glance.
            {"name": "eyes", "image": "../cat/cat-eyes.png", "features": eyes},
            {"name": "face", "image": "../cat/cat-face.png",
             "features": [f["id"] for f in features if f["id"] not in ("socket_l", "socket_r", "pupil_l", "pupil_r")]},
        ],
        "features": features,
    }


if __name__ == "__main__":
    (HERE / "cat-target.json").write_text(json.dumps(scene(), indent=1) + "\n")
    print(HERE / "cat-target.json")
