"""Copy the cat photograph and draw its mouth, then write the scene:
``python examples/cat/make_art.py``.

The photograph is "Chelsea", the CC0 cat that ships inside scikit-image
(``skimage.data.chelsea()``, 451 x 300). The drawing traced over it:

- ``ear_left``, ``ear_right``: the outer edges of the ears (splines), which twitch;
- ``lid_*_upper`` / ``lid_*_lower``: the eyelids (splines); the upper lids close onto the
  lower ones, which stay put, so each eye squeezes shut;
- ``mouth``: a ``cut`` along the mouth line, with ``lip`` above it held and ``jaw`` below it
  pulled down: the cut opens and shows ``mouth.png``, the inside of a mouth drawn here, on a
  layer behind the photograph;
- ``frame``: the left, top and right edges of the picture, held (away from the right ear),
  and ``nose`` held, so the rest of the face stays where it is.

``scene.json``: 2.5 s at 24 fps: an ear flick, a slow blink, a meow, a second ear flick.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

HERE = Path(__file__).resolve().parent
W, H = 451, 300
FPS = 24
DURATION = 2.5

# Traced over the photograph (pixel centres, y down).
EAR_RIGHT = np.array([[356, 74], [366, 53], [380, 31], [397, 6]], float)
EAR_LEFT = np.array([[42, 104], [37, 72], [36, 38], [40, 4]], float)
EYES = {
    "l": (np.array([[137, 118], [146, 97], [168, 86], [190, 89], [204, 106]], float),
          np.array([[137, 118], [150, 137], [172, 146], [193, 137], [204, 106]], float)),
    "r": (np.array([[299, 158], [301, 135], [312, 117], [330, 109], [346, 113]], float),
          np.array([[299, 158], [314, 164], [332, 157], [343, 138], [346, 113]], float)),
}
MOUTH_CUT = np.array([[221, 277], [238, 271], [255, 268], [272, 271], [289, 277]], float)
LIP = np.array([[224, 273], [255, 264], [286, 273]], float)
JAW = np.array([[226, 282], [255, 273], [284, 282]], float)
NOSE = np.array([[255, 240]], float)
FRAME = np.array([[0, H - 1], [0, 0], [300, 0]], float)  # left and top edges
FRAME_RIGHT = np.array([[W - 1, 130], [W - 1, H - 1]], float)


def channel(keys, t):
    """Smoothstep between (time, value) keys; holds before the first and after the last."""
    if t <= keys[0][0]:
        return keys[0][1]
    for (t0, v0), (t1, v1) in zip(keys, keys[1:]):
        if t <= t1:
            u = (t - t0) / (t1 - t0)
            return v0 + (v1 - v0) * u * u * (3 - 2 * u)
    return keys[-1][1]


FLICK_RIGHT = [(0.0, 0.0), (0.2, 0.0), (0.32, 1.0), (0.5, 0.0), (2.5, 0.0)]
FLICK_LEFT = [(0.0, 0.0), (1.95, 0.0), (2.07, 1.0), (2.25, 0.0), (2.5, 0.0)]
BLINK = [(0.0, 0.0), (0.7, 0.0), (0.9, 1.0), (1.05, 1.0), (1.25, 0.0), (2.5, 0.0)]
MEOW = [(0.0, 0.0), (1.3, 0.0), (1.55, 1.0), (1.8, 1.0), (2.05, 0.0), (2.5, 0.0)]


def rotate(points, degrees, pivot):
    a = math.radians(degrees)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return (np.asarray(points, float) - pivot) @ rot.T + pivot


def closed_lid(upper, lower):
    """The upper lid laid on the lower lid (1 px above it), corners unchanged."""
    shut = lower + [0, -1.0]
    shut[[0, -1]] = upper[[0, -1]]
    return shut


def pose_at(t):
    flick_r, flick_l = channel(FLICK_RIGHT, t), channel(FLICK_LEFT, t)
    blink, meow = channel(BLINK, t), channel(MEOW, t)
    out = {
        "ear_right": rotate(EAR_RIGHT, 9.0 * flick_r, EAR_RIGHT[0]),
        "ear_left": rotate(EAR_LEFT, -7.0 * flick_l, EAR_LEFT[0]),
        "jaw": JAW + [0, 11.0 * meow] + np.array([[-2, 0], [0, 0], [2, 0]]) * meow,
        "lip": LIP, "nose": NOSE, "frame": FRAME, "frame_right": FRAME_RIGHT,
        "mouth": MOUTH_CUT,
    }
    for side, (upper, lower) in EYES.items():
        out[f"lid_{side}_upper"] = (1 - blink) * upper + blink * closed_lid(upper, lower)
        out[f"lid_{side}_lower"] = lower
    return out


FEATURES = [  # id, kind, channels that move it
    ("frame", "polyline", ()),
    ("frame_right", "polyline", ()),
    ("nose", "point", ()),
    ("ear_right", "spline", (FLICK_RIGHT,)),
    ("ear_left", "spline", (FLICK_LEFT,)),
    ("lid_l_upper", "spline", (BLINK,)),
    ("lid_l_lower", "spline", ()),
    ("lid_r_upper", "spline", (BLINK,)),
    ("lid_r_lower", "spline", ()),
    ("lip", "spline", ()),
    ("jaw", "spline", (MEOW,)),
    ("mouth", "cut", ()),
]


def scene():
    rest = pose_at(0.0)
    features = []
    for fid, kind, channels in FEATURES:
        feature = {"id": fid, "kind": kind, "rest": _pts(rest[fid])}
        key_times = sorted({t for ch in channels for t, _ in ch})
        if key_times:
            feature["keys"] = [{"t": t, "points": _pts(pose_at(t)[fid])} for t in key_times]
        features.append(feature)
    return {
        "inkwarp": 1, "width": W, "height": H, "fps": FPS, "duration": DURATION,
        "background": [0, 0, 0, 255],
        "layers": [
            {"name": "mouth", "image": "mouth.png", "features": []},
            {"name": "cat", "image": "cat.png"},
        ],
        "features": features,
    }


def _pts(a):
    return [[round(float(x), 2), round(float(y), 2)] for x, y in np.asarray(a)]


def draw_mouth():
    """The inside of the mouth: dark at the back, a pink tongue, soft edges."""
    ss = 4
    img = Image.new("RGBA", (W * ss, H * ss), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)

    def ellipse(c, r, fill):
        d.ellipse([(c[0] - r[0]) * ss, (c[1] - r[1]) * ss, (c[0] + r[0]) * ss,
                   (c[1] + r[1]) * ss], fill=fill)

    ellipse((255, 279), (40, 16), (70, 22, 30, 255))
    ellipse((255, 289), (22, 9), (196, 96, 106, 255))
    img = img.filter(ImageFilter.GaussianBlur(1.5 * ss))
    return img.resize((W, H), Image.LANCZOS)


def main():
    from skimage import data

    Image.fromarray(data.chelsea()).save(HERE / "cat.png", optimize=True)
    draw_mouth().save(HERE / "mouth.png", optimize=True)
    (HERE / "scene.json").write_text(json.dumps(scene(), indent=1) + "\n")
    for name in ("cat.png", "mouth.png", "scene.json"):
        print(HERE / name)


if __name__ == "__main__":
    main()
