"""Make the pictures of docs/guides/first-animation.md by following the guide.

``python docs/guides/first-animation/make_pictures.py`` (with the package installed) runs
the guide's commands in a temporary directory, as a reader would, and keeps its outputs
here: drawing.png (the traced drawing over the photograph), rest.png, flick.png,
field.png, meow.png and strip.png (frames of the final animation side by side).
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
GUIDE = HERE.parent / "first-animation.md"
FENCE = re.compile(r"(?:<!-- file: (?P<file>\S+) -->\n)?```(?P<lang>\w*)\n(?P<body>.*?)```",
                   re.S)
COLOURS = {"spline": (40, 220, 60), "point": (230, 30, 30), "polyline": (40, 110, 240),
           "cut": (230, 40, 230), "region": (250, 220, 0)}


def follow_the_guide(work: Path) -> str:
    """Run every command of the guide in ``work``; return its first scene file's text."""
    import os

    from inkwarp.cli import main

    os.chdir(work)  # the guide's paths are relative to the repository's root
    first_scene = None
    for m in FENCE.finditer(GUIDE.read_text()):
        if m["file"]:
            (work / m["file"]).write_text(m["body"])
            first_scene = first_scene or m["body"]
        elif m["lang"] == "sh":
            for line in m["body"].splitlines():
                words = shlex.split(line, comments=True)
                if words[:1] == ["inkwarp"]:
                    assert main([*words[1:], "--quiet"] if words[1] == "render"
                                else words[1:]) == 0, line
                elif words[:2] == ["mkdir", "-p"]:
                    (work / words[2]).mkdir(parents=True, exist_ok=True)
                elif words[:1] == ["cp"]:
                    shutil.copy(work / words[1], work / words[2])
    assert first_scene is not None
    return first_scene


def catmull_rom(points, per_span=16):
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


def drawing_over(picture: Path, scene_text: str, scale: int = 2) -> Image.Image:
    image = Image.open(picture).convert("RGB")
    image = image.resize((image.width * scale, image.height * scale), Image.LANCZOS)
    draw = ImageDraw.Draw(image)
    for feature in json.loads(scene_text)["features"]:
        points = np.asarray(feature["rest"], float)
        colour = COLOURS[feature["kind"]]
        line = catmull_rom(points) if feature["kind"] == "spline" else points
        if len(line) > 1:
            draw.line([tuple(q * scale) for q in line], fill=colour, width=6)
        for x, y in points * scale:
            draw.ellipse([x - 5, y - 5, x + 5, y + 5], fill=colour, outline=(0, 0, 0))
    return image


def strip(scene: Path, times: list[float], scale: float = 0.5) -> Image.Image:
    import inkwarp

    s = inkwarp.Scene.load(str(scene))
    frames = [Image.fromarray(s.render(time=t)).convert("RGB") for t in times]
    w, h = int(frames[0].width * scale), int(frames[0].height * scale)
    sheet = Image.new("RGB", (len(frames) * (w + 4) - 4, h), (255, 255, 255))
    for i, frame in enumerate(frames):
        sheet.paste(frame.resize((w, h), Image.LANCZOS), (i * (w + 4), 0))
    return sheet


def main():
    import os

    import inkwarp

    home = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        shutil.copytree(ROOT / "examples", work / "examples")
        first_scene = follow_the_guide(work)
        cat = work / "my-cat"
        drawing_over(cat / "cat.png", first_scene).save(HERE / "drawing.png", optimize=True)
        rest = inkwarp.Scene.load(str(cat / "scene.json")).render(time=0.0)
        Image.fromarray(rest).convert("RGB").save(HERE / "rest.png", optimize=True)
        for name in ("flick.png", "field.png", "meow.png"):
            Image.open(cat / name).convert("RGB").save(HERE / name, optimize=True)
        strip(cat / "scene.json", [0.0, 0.4, 0.9, 1.4, 1.9]).save(HERE / "strip.png",
                                                                  optimize=True)
        os.chdir(home)
    for name in ("drawing.png", "rest.png", "flick.png", "field.png", "meow.png", "strip.png"):
        print(HERE / name)


if __name__ == "__main__":
    main()
