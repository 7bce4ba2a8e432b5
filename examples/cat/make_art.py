"""Copy the cat photograph, cut it into layers, draw its mouth, then write the scene:
``python examples/cat/make_art.py``.

The photograph is "Chelsea", the CC0 cat that ships inside scikit-image
(``skimage.data.chelsea()``, 451 x 300), copied to ``cat.png``. As in Figure 1 of the
paper, the eyes go on a layer of their own behind the face, so that the lids can close
over them: ``cat-face.png`` is the photograph with holes where the eyes are, and
``cat-eyes.png`` the eyes (a little more than the holes, so no gap shows), behind it.
Behind both, ``mouth.png`` is the inside of a mouth drawn here. The drawing traced over
the photograph:

- ``ear_left``, ``ear_right``: the outer edges of the ears (splines), which twitch;
- ``lid_*_upper`` / ``lid_*_lower``: the eyelids (splines), a pixel and a half outside the
  holes; the upper lids close over the eyes onto the lower lids, which stay put (the hole
  between them is a tear in the surface), while the ``brow_*`` curves above them dip;
- ``mouth``: a ``cut`` along the mouth line, with ``lip`` above it held and ``jaw`` below it
  pulled down: the cut opens and shows ``mouth.png``, the inside of a mouth drawn here, on a
  layer behind the photograph;
- ``frame``, ``frame_right``: the edges of the picture, held (away from the right ear),
  and ``nose`` held, so the rest of the face stays where it is.

``scene.json``: 2.5 s at 24 fps: an ear flick, a slow blink, a meow, a second ear flick.
"""

from __future__ import annotations

import json
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
# Held above the eyes, so a blink stretches the lid and not the whole forehead.
BROWS = {"l": np.array([[132, 98], [150, 74], [172, 66], [196, 72], [212, 92]], float),
         "r": np.array([[290, 128], [296, 104], [314, 90], [336, 88], [356, 102]], float)}
MOUTH_CUT = np.array([[221, 277], [238, 271], [255, 268], [272, 271], [289, 277]], float)
LIP = np.array([[224, 273], [255, 264], [286, 273]], float)
JAW = np.array([[226, 282], [255, 273], [284, 282]], float)
NOSE = np.array([[255, 240]], float)
FRAME = np.array([[0, H - 1], [0, 0], [300, 0]], float)  # left and top edges
FRAME_RIGHT = np.array([[W - 1, 130], [W - 1, H - 1], [0, H - 1]], float)  # and the bottom


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


def flick(points, tip_dx):
    """An ear flicked sideways: its base stays, its tip (on the picture's edge) slides
    ``tip_dx`` pixels along that edge, the points between in proportion to their height."""
    pts = np.asarray(points, float)
    share = (pts[0, 1] - pts[:, 1]) / (pts[0, 1] - pts[-1, 1])
    return pts + np.stack([tip_dx * share, np.zeros(len(pts))], axis=1)


def shut_lid(upper, lower, blink):
    """The upper lid ``blink`` of the way to shut: at 1 it lies two pixels over the lower
    lid's edge (so no sliver of the eye shows), corners unchanged."""
    shut = lower + [0, 2.0]
    shut[[0, -1]] = upper[[0, -1]]
    return (1 - blink) * upper + blink * shut


def catmull_rom(points, per_span=24):
    """Dense polyline of the centripetal Catmull-Rom spline through ``points`` (the curve
    the engine samples), for cutting the holes along the traced lids."""
    p = [np.asarray(q, float) for q in points]
    ext = [2 * p[0] - p[1], *p, 2 * p[-1] - p[-2]]
    out = []
    for i in range(len(ext) - 3):
        p0, p1, p2, p3 = ext[i:i + 4]
        t1 = np.linalg.norm(p1 - p0) ** 0.5
        t2 = t1 + np.linalg.norm(p2 - p1) ** 0.5
        t3 = t2 + np.linalg.norm(p3 - p2) ** 0.5
        for t in np.linspace(t1, t2, per_span, endpoint=False):
            a1 = (t1 - t) / t1 * p0 + t / t1 * p1
            a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2
            a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3
            b1 = (t2 - t) / t2 * a1 + t / t2 * a2
            b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3
            out.append((t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2)
    out.append(p[-1])
    return np.array(out)


def pose_at(t):
    flick_r, flick_l = channel(FLICK_RIGHT, t), channel(FLICK_LEFT, t)
    blink, meow = channel(BLINK, t), channel(MEOW, t)
    out = {
        "ear_right": flick(EAR_RIGHT, 12.0 * flick_r),
        "ear_left": flick(EAR_LEFT, -8.0 * flick_l),
        "jaw": JAW + np.array([[-2, 4], [0, 11], [2, 4]]) * meow,  # drops, most in the middle
        "lip": LIP, "nose": NOSE, "frame": FRAME, "frame_right": FRAME_RIGHT,
        "mouth": MOUTH_CUT,
    }
    for side, (upper, lower) in EYES.items():
        out[f"lid_{side}_upper"] = shut_lid(upper, lower, blink)
        out[f"lid_{side}_lower"] = lower
        out[f"brow_{side}"] = BROWS[side] + blink * np.outer([0.3, 0.8, 1, 0.8, 0.3], [0, 9])
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
    ("brow_l", "spline", (BLINK,)),
    ("brow_r", "spline", (BLINK,)),
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
            {"name": "eyes", "image": "cat-eyes.png", "features": []},
            {"name": "face", "image": "cat-face.png"},
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
    return img.reduce(ss)  # block means: exact coverage, no ringing


def eye_holes(ss=4, inset_px=1.5):
    """Where the eyes are: inside the traced lids, less ``inset_px`` all round (so the lids
    lie on fur, where their samples take hold), as a boolean (H, W) mask."""
    mask = Image.new("L", (W * ss, H * ss), 0)
    d = ImageDraw.Draw(mask)
    for upper, lower in EYES.values():
        outline = np.concatenate([catmull_rom(upper), catmull_rom(lower)[::-1]])
        d.polygon([(x * ss, y * ss) for x, y in outline], fill=255)
    mask = mask.filter(ImageFilter.MinFilter(2 * int(inset_px * ss) + 1))
    return np.asarray(mask.reduce(ss)) >= 128


def split_photo(photo):
    """(face, eyes): the photograph with the eyes cut out, and the eyes alone, reaching
    6 px past the holes under the fur."""
    holes = eye_holes()
    face = np.dstack([photo, np.where(holes, 0, 255).astype(np.uint8)])
    grown = np.asarray(Image.fromarray(holes.astype(np.uint8) * 255).filter(
        ImageFilter.MaxFilter(13))) > 0
    eyes = np.dstack([photo, np.where(grown, 255, 0).astype(np.uint8)])
    return face, eyes


def main():
    from skimage import data

    photo = data.chelsea()
    face, eyes = split_photo(photo)
    Image.fromarray(photo).save(HERE / "cat.png", optimize=True)
    Image.fromarray(face).save(HERE / "cat-face.png", optimize=True)
    Image.fromarray(eyes).save(HERE / "cat-eyes.png", optimize=True)
    draw_mouth().save(HERE / "mouth.png", optimize=True)
    (HERE / "scene.json").write_text(json.dumps(scene(), indent=1) + "\n")
    for name in ("cat.png", "cat-face.png", "cat-eyes.png", "mouth.png", "scene.json"):
        print(HERE / name)


if __name__ == "__main__":
    main()
