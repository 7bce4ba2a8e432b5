"""Render the previews committed beside each example: ``python examples/render_previews.py``.

`make demo` renders every example in full (GIF and MP4) into ``out/``; these are the small
copies the READMEs show: ``face/face.gif``, ``cat/cat.mp4`` and ``cat/frames.png`` (a GIF
of a photograph would be megabytes), and the two checkerboard GIFs.
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image

import inkwarp
from inkwarp.video import write_frames

HERE = Path(__file__).resolve().parent


def strip(scene, times, scale=0.5, gap=4):
    """Frames at ``times`` side by side, scaled down."""
    frames = [Image.fromarray(scene.render(time=t)).convert("RGB") for t in times]
    w, h = int(frames[0].width * scale), int(frames[0].height * scale)
    sheet = Image.new("RGB", (len(frames) * (w + gap) - gap, h), (255, 255, 255))
    for i, frame in enumerate(frames):
        sheet.paste(frame.resize((w, h), Image.LANCZOS), (i * (w + gap), 0))
    return sheet


def main():
    written = []
    for scene_path, outputs in [
        ("face/scene.json", ["face/face.gif"]),
        ("cat/scene.json", ["cat/cat.mp4"]),
        ("checkerboard-hole/with-hole.json", ["checkerboard-hole/with-hole.gif"]),
        ("checkerboard-hole/without-hole.json", ["checkerboard-hole/without-hole.gif"]),
    ]:
        scene = inkwarp.Scene.load(HERE / scene_path)
        frames = list(scene.frames())
        for output in outputs:
            written += write_frames(HERE / output, frames, fps=scene.fps)
    cat = inkwarp.Scene.load(HERE / "cat" / "scene.json")
    sheet = strip(cat, [0.0, 0.32, 0.95, 1.6, 2.07])
    sheet.save(HERE / "cat" / "frames.png", optimize=True)
    written.append(HERE / "cat" / "frames.png")
    for path in written:
        print(path)


if __name__ == "__main__":
    main()
