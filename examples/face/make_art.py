"""Draw the face example's art and write its scene: ``python examples/face/make_art.py``.

A cartoon character on two layers, as in Figure 1 of Litwinowicz & Williams:

- ``face.png`` (front): head, hair, ears, neck and shirt, with *holes* (alpha 0) where the
  eyes and the mouth show through. Its continuity matte is its alpha (the default), so the
  holes are also tears in its surface: the upper lid can close without dragging the lower
  lid, and the lips part.
- ``eyes.png`` (back): eyeballs and the inside of the mouth, larger than the holes so no gap
  ever shows. ``eyes_continuity.png`` (all white) makes this layer one connected sheet, so
  the head's outline moves it too (continuity and transparency are independent mattes).

``scene.json``: 2.5 s at 24 fps. The character smiles, tilts its head, blinks (the upper lids
close onto the lower lids, which stay put) and glances to the side. Every key is computed
here from a few animation channels (tilt, smile, blink, glance), so the drawing traces the
art exactly.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

HERE = Path(__file__).resolve().parent
SIZE = 384
SS = 4  # supersampling for antialiased drawing
FPS = 24
DURATION = 2.5

SKIN = (250, 208, 172, 255)
SKIN_SHADE = (232, 180, 146, 255)
INK = (58, 38, 32, 255)
HAIR = (96, 58, 36, 255)
SHIRT = (64, 112, 176, 255)
BACKGROUND = [226, 238, 246, 255]

HEAD_C, HEAD_R = (192.0, 170.0), (108.0, 124.0)
PIVOT = (192.0, 292.0)  # the head tilts about the top of the neck
EYES = {"l": (150.0, 168.0), "r": (234.0, 168.0)}


# --- geometry ------------------------------------------------------------------------------

def catmull_rom(points, closed=False, per_span=24):
    """Dense polyline of the centripetal Catmull-Rom spline through ``points`` (the same
    curve the engine samples: reflected phantom end points for an open curve)."""
    p = [np.asarray(q, float) for q in points]
    if closed:
        ext = [p[-1], *p, p[0], p[1]]
    else:
        ext = [2 * p[0] - p[1], *p, 2 * p[-1] - p[-2]]
    out = []
    for i in range(len(ext) - 3):
        p0, p1, p2, p3 = ext[i:i + 4]
        t0 = 0.0
        t1 = t0 + max(np.linalg.norm(p1 - p0), 1e-9) ** 0.5
        t2 = t1 + max(np.linalg.norm(p2 - p1), 1e-9) ** 0.5
        t3 = t2 + max(np.linalg.norm(p3 - p2), 1e-9) ** 0.5
        for t in np.linspace(t1, t2, per_span, endpoint=False):
            a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1
            a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2
            a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3
            b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2
            b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3
            out.append((t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2)
    if not closed:
        out.append(p[-1])
    return np.array(out)


def ellipse_points(c, r, n, start_deg=-90.0):
    a = np.radians(start_deg + np.arange(n) * 360.0 / n)
    return np.stack([c[0] + r[0] * np.cos(a), c[1] + r[1] * np.sin(a)], axis=1)


def rotate(points, degrees, pivot=PIVOT):
    a = math.radians(degrees)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return (np.asarray(points, float) - pivot) @ rot.T + pivot


def lids(eye, blink=0.0):
    """(upper, lower) lid control points of one eye; ``blink`` 1 lays the upper lid on the
    lower one (just over its edge, so no sliver of the eye shows between them)."""
    cx, cy = eye
    upper = np.array([[-28, 2], [-15, -14], [0, -19], [15, -14], [28, 2]], float)
    lower = np.array([[-28, 2], [-13, 13], [0, 16], [13, 13], [28, 2]], float)
    closed = lower + [0, 2.0]  # two pixels past the lower lid's edge, so the lids overlap
    closed[[0, -1]] = upper[[0, -1]]
    upper = (1 - blink) * upper + blink * closed
    return upper + (cx, cy), lower + (cx, cy)


def brow(eye, raise_px=0.0):
    cx, cy = eye
    side = -1 if cx < HEAD_C[0] else 1
    pts = np.array([[-26 * side, -41], [0, -46], [26 * side, -37]], float)
    pts[:, 1] -= raise_px * np.array([0.6, 1.0, 1.2])
    return pts + (cx, cy)


def lips(smile=0.0):
    """(upper, lower) lip control points: a small open mouth at 0, a wide grin at 1."""
    neutral_u = np.array([[162, 248], [177, 244], [192, 245], [207, 244], [222, 248]], float)
    neutral_l = np.array([[162, 248], [177, 256], [192, 259], [207, 256], [222, 248]], float)
    grin_u = np.array([[150, 236], [171, 243], [192, 245], [213, 243], [234, 236]], float)
    grin_l = np.array([[150, 236], [169, 261], [192, 270], [215, 261], [234, 236]], float)
    return (1 - smile) * neutral_u + smile * grin_u, (1 - smile) * neutral_l + smile * grin_l


def socket(eye):
    return ellipse_points((eye[0], eye[1] - 1), (35, 26), 8)


SHOULDERS = np.array([[40, 383], [62, 345], [130, 322], [254, 322], [322, 345], [344, 383]],
                     float)
NOSE = np.array([[189, 196], [184, 214], [194, 218]], float)


# --- animation channels (value at time t) ---------------------------------------------------

def channel(keys, t):
    """Smoothstep between (time, value) keys; holds before the first and after the last."""
    if t <= keys[0][0]:
        return keys[0][1]
    for (t0, v0), (t1, v1) in zip(keys, keys[1:]):
        if t <= t1:
            u = (t - t0) / (t1 - t0)
            return v0 + (v1 - v0) * u * u * (3 - 2 * u)
    return keys[-1][1]


TILT = [(0.0, 0.0), (0.7, 7.0), (1.5, 7.0), (2.1, -2.0), (2.5, 0.0)]
SMILE = [(0.0, 0.0), (0.55, 1.0), (1.8, 1.0), (2.35, 0.0), (2.5, 0.0)]
BLINK = [(0.0, 0.0), (0.95, 0.0), (1.05, 1.0), (1.2, 0.0), (2.5, 0.0)]
GLANCE = [(0.0, 0.0), (1.3, 0.0), (1.55, 6.0), (1.95, 6.0), (2.2, 0.0), (2.5, 0.0)]


def times(*channels):
    return sorted({t for ch in channels for t, _ in ch})


def pose_at(t):
    """Every feature's control points at time t."""
    tilt, smile = channel(TILT, t), channel(SMILE, t)
    blink, glance = channel(BLINK, t), channel(GLANCE, t)
    out = {"head": rotate(ellipse_points(HEAD_C, HEAD_R, 12), tilt), "shoulders": SHOULDERS,
           "nose": rotate(NOSE, tilt)}
    for side, eye in EYES.items():
        upper, lower = lids(eye, blink)
        out[f"lid_{side}_upper"] = rotate(upper, tilt)
        out[f"lid_{side}_lower"] = rotate(lower, tilt)
        out[f"brow_{side}"] = rotate(brow(eye, 5.0 * smile), tilt)
        out[f"socket_{side}"] = rotate(socket(eye), tilt)
        out[f"pupil_{side}"] = rotate([[eye[0] + glance, eye[1] - 1 - 0.3 * glance]], tilt)
    upper, lower = lips(smile)
    out["lip_upper"], out["lip_lower"] = rotate(upper, tilt), rotate(lower, tilt)
    return out


FEATURES = [  # id, kind, closed, channels that move it
    ("head", "spline", True, (TILT,)),
    ("shoulders", "polyline", False, ()),
    ("nose", "spline", False, (TILT,)),
    ("brow_l", "spline", False, (TILT, SMILE)),
    ("brow_r", "spline", False, (TILT, SMILE)),
    ("lid_l_upper", "spline", False, (TILT, BLINK)),
    ("lid_l_lower", "spline", False, (TILT,)),
    ("lid_r_upper", "spline", False, (TILT, BLINK)),
    ("lid_r_lower", "spline", False, (TILT,)),
    ("lip_upper", "spline", False, (TILT, SMILE)),
    ("lip_lower", "spline", False, (TILT, SMILE)),
    ("socket_l", "polyline", True, (TILT,)),
    ("socket_r", "polyline", True, (TILT,)),
    ("pupil_l", "point", False, (TILT, GLANCE)),
    ("pupil_r", "point", False, (TILT, GLANCE)),
]
FACE_FEATURES = ["head", "shoulders", "nose", "brow_l", "brow_r", "lid_l_upper",
                 "lid_l_lower", "lid_r_upper", "lid_r_lower", "lip_upper", "lip_lower"]
EYES_FEATURES = ["head", "shoulders", "socket_l", "socket_r", "pupil_l", "pupil_r",
                 "lip_upper", "lip_lower"]


def scene():
    rest = pose_at(0.0)
    features = []
    for fid, kind, closed, channels in FEATURES:
        feature = {"id": fid, "kind": kind, "rest": _pts(rest[fid])}
        if closed:
            feature["closed"] = True
        if channels:
            keys = []
            for t in times(*channels):
                key = {"t": t, "points": _pts(pose_at(t)[fid])}
                # The blink is quick and exact: straight lines between open, shut and open
                # (a smooth curve through them would push the lid past the lower lid).
                if BLINK in channels and 0.7 <= t < 1.2:
                    key["interpolation"] = "linear"
                keys.append(key)
            feature["keys"] = keys
        features.append(feature)
    return {
        "inkwarp": 1, "width": SIZE, "height": SIZE, "fps": FPS, "duration": DURATION,
        "background": BACKGROUND,
        "layers": [
            {"name": "eyes", "image": "eyes.png", "continuity": "eyes_continuity.png",
             "features": EYES_FEATURES},
            {"name": "face", "image": "face.png", "features": FACE_FEATURES},
        ],
        "features": features,
    }


def _pts(a):
    return [[round(float(x), 2), round(float(y), 2)] for x, y in np.asarray(a)]


# --- drawing -------------------------------------------------------------------------------

def _s(points):
    return [(float(x) * SS, float(y) * SS) for x, y in np.asarray(points)]


def _ellipse(draw, c, r, **kw):
    draw.ellipse([(c[0] - r[0]) * SS, (c[1] - r[1]) * SS, (c[0] + r[0]) * SS,
                  (c[1] + r[1]) * SS], **kw)


def _stroke(draw, points, width, fill=INK):
    pts = _s(points)
    draw.line(pts, fill=fill, width=int(width * SS), joint="curve")
    for end in (pts[0], pts[-1]):
        r = width * SS / 2
        draw.ellipse([end[0] - r, end[1] - r, end[0] + r, end[1] + r], fill=fill)


def _finish(img):
    # The mean of each SS x SS block: exact coverage, no ringing. (A Lanczos filter would
    # ring around the holes, leaving faint specks of alpha inside them, and every speck is
    # surface that the continuity matte connects.)
    return img.reduce(SS)


def draw_face():
    img = Image.new("RGBA", (SIZE * SS, SIZE * SS), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)
    # shirt and neck
    shirt = np.concatenate([catmull_rom(SHOULDERS[1:-1], per_span=12),
                            [[344, 390], [40, 390]]])
    d.polygon(_s(np.concatenate([[[62, 345]], shirt])), fill=SHIRT, outline=INK,
              width=3 * SS)
    d.rectangle([166 * SS, 262 * SS, 218 * SS, 330 * SS], fill=SKIN_SHADE)
    _stroke(d, [[166, 270], [166, 326]], 3)
    _stroke(d, [[218, 270], [218, 326]], 3)
    collar = catmull_rom([[150, 322], [192, 346], [234, 322]], per_span=16)
    _stroke(d, collar, 4, fill=(240, 240, 240, 255))
    # ears, behind the head
    for ex in (86.0, 298.0):
        _ellipse(d, (ex, 180.0), (19, 29), fill=SKIN, outline=INK, width=3 * SS)
        _ellipse(d, (ex, 182.0), (8, 16), fill=SKIN_SHADE)
    # head
    _ellipse(d, HEAD_C, HEAD_R, fill=SKIN, outline=INK, width=3 * SS)
    # hair: the top of a slightly larger ellipse, cut off along a wavy fringe
    hair = Image.new("L", img.size, 0)
    hd = ImageDraw.Draw(hair)
    _ellipse(hd, (192.0, 160.0), (116.0, 132.0), fill=255)
    xs = np.arange(SIZE * SS) / SS
    fringe = 92 + 9 * np.abs(np.sin((xs - 192) / 19.0)) + 95 * (np.abs(xs - 192) / 118) ** 5
    rows = np.arange(SIZE * SS)[:, None] / SS
    cut = np.asarray(hair) * (rows < fringe[None, :])
    hair = Image.fromarray(cut.astype(np.uint8))
    img.paste(Image.new("RGBA", img.size, HAIR), (0, 0), hair)
    outline = hair.filter(ImageFilter.FIND_EDGES).point(lambda v: 255 if v > 40 else 0)
    outline = outline.filter(ImageFilter.MaxFilter(2 * SS + 1))
    hair_ink = Image.composite(Image.new("RGBA", img.size, INK), img, outline)
    img = Image.composite(hair_ink, img, hair.filter(ImageFilter.MaxFilter(2 * SS + 1)))
    d = ImageDraw.Draw(img)
    for x0 in (150, 176, 204, 230):  # a few strands
        _stroke(d, catmull_rom([[x0, 62], [x0 + 6, 78], [x0 + 2, 94]], per_span=10), 2,
                fill=(70, 40, 26, 255))
    # cheeks, nose, brows
    blush = Image.new("RGBA", img.size, (0, 0, 0, 0))
    bd = ImageDraw.Draw(blush)
    for cx in (118.0, 266.0):
        _ellipse(bd, (cx, 222.0), (20, 12), fill=(240, 130, 130, 110))
    img.alpha_composite(blush.filter(ImageFilter.GaussianBlur(4 * SS)))
    d = ImageDraw.Draw(img)
    _stroke(d, catmull_rom(NOSE, per_span=12), 3, fill=(190, 120, 90, 255))
    rest = pose_at(0.0)
    for side in EYES:
        _stroke(d, catmull_rom(rest[f"brow_{side}"], per_span=12), 7, fill=HAIR)
    # eyes: the lash line and a few lashes on the upper lid, a thin lower lid, then the hole
    holes = Image.new("L", img.size, 0)
    hd = ImageDraw.Draw(holes)
    for side, eye in EYES.items():
        upper = catmull_rom(rest[f"lid_{side}_upper"])
        lower = catmull_rom(rest[f"lid_{side}_lower"])
        _stroke(d, lower, 3.5, fill=(150, 95, 75, 255))
        _stroke(d, upper, 8)
        out = -1 if eye[0] < HEAD_C[0] else 1
        roots = upper[::12][1:-1]
        for k, (lx, ly) in enumerate(roots):
            toward_outer = k if out > 0 else len(roots) - 1 - k  # longer sweep at the corner
            tip = (lx + out * (3 + 3 * toward_outer), ly - 7)
            _stroke(d, [(lx, ly - 2), tip], 2.5)
        hd.polygon(_s(np.concatenate([upper, lower[::-1]])), fill=255)
    # mouth: the lip line around the hole
    upper, lower = catmull_rom(rest["lip_upper"]), catmull_rom(rest["lip_lower"])
    _stroke(d, np.concatenate([upper, lower[::-1][1:]]), 6, fill=(120, 40, 40, 255))
    hd.polygon(_s(np.concatenate([upper, lower[::-1]])), fill=255)
    face = np.array(_finish(img))
    # The holes get a hard edge (a pixel is in a hole when most of it is): the renderer
    # antialiases every edge of the surface as it draws, and a soft rim of half-transparent
    # skin would let the eyes show through when the lid is stretched shut over it.
    # The holes are also drawn a pixel and a half inside the traced lids and lips, so that
    # the drawing lies on skin: a sample whose nearest pixel is in a hole constrains nothing.
    holes = holes.filter(ImageFilter.MinFilter(2 * int(1.5 * SS) + 1))
    hole = np.asarray(holes.reduce(SS)) >= 128
    face[hole, 3] = 0
    return Image.fromarray(face)


def draw_eyes():
    img = Image.new("RGBA", (SIZE * SS, SIZE * SS), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)
    for eye in EYES.values():
        _ellipse(d, (eye[0], eye[1] - 1), (40, 30), fill=(252, 252, 250, 255))
        _ellipse(d, (eye[0], eye[1] - 1), (13, 13), fill=(70, 120, 170, 255),
                 outline=(30, 50, 80, 255), width=2 * SS)
        _ellipse(d, (eye[0], eye[1] - 1), (6, 6), fill=(15, 15, 20, 255))
        _ellipse(d, (eye[0] - 4, eye[1] - 6), (2.5, 2.5), fill=(255, 255, 255, 255))
    _ellipse(d, (192.0, 254.0), (56, 34), fill=(100, 24, 36, 255))
    _ellipse(d, (192.0, 276.0), (30, 15), fill=(222, 104, 116, 255))
    d.rounded_rectangle([160 * SS, 236 * SS, 224 * SS, 251 * SS], radius=5 * SS,
                        fill=(250, 250, 246, 255))
    return _finish(img)


def main():
    draw_face().save(HERE / "face.png", optimize=True)
    draw_eyes().save(HERE / "eyes.png", optimize=True)
    Image.new("L", (SIZE, SIZE), 255).save(HERE / "eyes_continuity.png", optimize=True)
    (HERE / "scene.json").write_text(json.dumps(scene(), indent=1) + "\n")
    for name in ("face.png", "eyes.png", "eyes_continuity.png", "scene.json"):
        print(HERE / name)


if __name__ == "__main__":
    main()
