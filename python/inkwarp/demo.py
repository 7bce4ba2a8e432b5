"""The demo: a still warp made from nothing but code, and the example animations.

:func:`run` is what ``inkwarp demo`` and ``make demo`` call. :func:`stills` warps a
generated picture by a curve, a point and a hole in its continuity matte and writes
``before.png``, ``after.png``, ``matte.png`` and ``field.png`` (the displacement field as a
picture); :func:`render_example` renders one of the scenes in ``examples/`` to GIF and MP4.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp.errors import InputError

#: The example scenes, by example name (the directory in ``examples/``).
EXAMPLES: dict[str, tuple[str, ...]] = {
    "face": ("scene.json",),
    "cat": ("scene.json",),
    "checkerboard-hole": ("with-hole.json", "without-hole.json"),
}

#: Demo parts beyond the examples: the paper's comparison plates, its animation
#: transfer (the face's motion on the cat) and its actor-to-cat pipeline (the actor video
#: tracked, then transferred onto the cat).
EXTRA_PARTS: tuple[str, ...] = ("compare", "transfer", "rotoscope")

#: The formats an animation can be rendered to by the demo.
FORMATS = ("gif", "mp4")

#: Size of the still demo's picture (width, height).
STILL_SIZE = (320, 240)


def find_examples(path: str | os.PathLike[str] | None = None) -> Path:
    """The directory holding the example scenes.

    ``path`` if given, else ``$INKWARP_EXAMPLES``, else ``examples/`` of the source
    checkout this package runs from, else the copy a wheel ships (``inkwarp/examples/``,
    put there by ``make wheel``).
    """
    given = path
    if path is None:
        checkout = Path(__file__).resolve().parents[2] / "examples"
        shipped = Path(__file__).resolve().parent / "examples"
        path = os.environ.get("INKWARP_EXAMPLES") or (
            checkout if (checkout / "face" / "scene.json").is_file() else shipped)
    found = Path(path)
    if not (found / "face" / "scene.json").is_file():
        fix = ("give the examples/ folder of a source checkout of inkwarp" if given is not None else
               "run the demo from a source checkout of inkwarp, or pass --examples DIR")
        raise InputError(f"{found}: no example scenes there (face/scene.json is missing); {fix}")
    return found


def run(out_dir: str | os.PathLike[str] = "out", *, only: Sequence[str] | None = None,
        formats: Sequence[str] = FORMATS, examples_dir: str | os.PathLike[str] | None = None,
        quiet: bool = False, log: Callable[[str], None] = print) -> list[Path]:
    """Render the demo into ``out_dir``; log and return every path written.

    Parameters
    ----------
    out_dir : path
        Created if missing.
    only : list of str, optional
        Parts to render: ``"stills"`` and names from :data:`EXAMPLES` (default: all).
    formats : list of str
        Animation formats, from :data:`FORMATS`.
    examples_dir : path, optional
        See :func:`find_examples`.
    quiet : bool
        No progress bars.
    log : callable
        Called with one line per file written (path, then what it is and how long it took).
    """
    for fmt in formats:
        if fmt not in FORMATS:
            raise InputError(f"--formats: unknown format '{fmt}'; use "
                             + " or ".join(FORMATS))
    if not formats:
        raise InputError("--formats: give at least one of " + ", ".join(FORMATS))
    parts = list(only) if only else ["stills", *EXAMPLES, *EXTRA_PARTS]
    for part in parts:
        if part != "stills" and part not in EXAMPLES and part not in EXTRA_PARTS:
            raise InputError(f"unknown demo part '{part}'; use stills or "
                             + ", ".join([*EXAMPLES, *EXTRA_PARTS]))
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: is a file; name a directory for the demo's output")
    root = None
    if any(part != "stills" for part in parts):
        root = find_examples(examples_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for part in parts:
        if part == "stills":
            started = time.perf_counter()
            paths = stills(out)
            seconds = time.perf_counter() - started
            for p in paths:
                log(f"{p}")
            log(f"  (stills in {seconds:.2f} s)")
            written += paths
            continue
        assert root is not None
        if part in EXTRA_PARTS:
            started = time.perf_counter()
            paths = _extra_part(part, root, out, formats, quiet)
            for p in paths:
                log(f"{p}")
            log(f"  ({part} in {time.perf_counter() - started:.2f} s)")
            written += paths
            continue
        for scene_name in EXAMPLES[part]:
            scene_path = root / part / scene_name
            stem = part if scene_name == "scene.json" else f"{part}-{Path(scene_name).stem}"
            targets = [out / f"{stem}.{fmt}" for fmt in formats]
            paths, info = render_example(scene_path, targets, quiet=quiet)
            for p in paths:
                log(f"{p}")
            log(f"  ({info})")
            written += paths
    return written


def _extra_part(part: str, root: Path, out: Path, formats: Sequence[str], quiet: bool) -> list[Path]:
    """The comparison plates, or the transferred animation (built, then rendered)."""
    if part == "compare":
        from inkwarp.compare import checkerboard_plates

        return checkerboard_plates(root, out)
    if part == "rotoscope":
        from inkwarp.track import rotoscope_example

        tracked, scene_path = rotoscope_example(root, out, quiet=quiet)
        paths, _info = render_example(scene_path, [out / f"rotoscope.{fmt}" for fmt in formats],
                                      quiet=quiet)
        return [tracked, scene_path, *paths]
    from inkwarp.transfer import transfer_example

    scene_path = transfer_example(root, out)
    paths, _info = render_example(scene_path, [out / f"transfer.{fmt}" for fmt in formats], quiet=quiet)
    return [scene_path, *paths]


def render_example(scene_path: str | os.PathLike[str], targets: Sequence[Path], *,
                   quiet: bool = False) -> tuple[list[Path], str]:
    """Render every frame of a scene once, into each of ``targets`` (.gif, .mp4, ...).

    Returns the paths written and a line saying how long it took.
    """
    import inkwarp
    from inkwarp import video
    from inkwarp.cli import _common

    scene = inkwarp.Scene.load(str(scene_path))
    count = scene.frame_count
    started = time.perf_counter()
    with contextlib.ExitStack() as stack:
        writers = [stack.enter_context(video.open_writer(t, fps=scene.fps)) for t in targets]
        # Named by what it writes: scenes made in one folder (the transfer and rotoscope
        # results, the checkerboard with and without its hole) shared its name.
        frames = _common.progress(scene.frames(), count, quiet=quiet,
                                  desc=Path(targets[0]).stem if targets else Path(scene_path).stem)
        for frame in frames:
            for writer in writers:
                writer.write(frame)
    seconds = time.perf_counter() - started
    info = (f"{count} frames of {scene.width}x{scene.height} at {scene.fps:g} fps in "
            f"{seconds:.2f} s, {1000 * seconds / max(count, 1):.0f} ms a frame, from "
            f"{scene_path}")
    return [p for w in writers for p in w.paths], info


def still_picture(width: int = STILL_SIZE[0], height: int = STILL_SIZE[1]) -> np.ndarray:
    """The still demo's picture: a sky, a sun, hills, and a grid that shows every bend.

    A vertical slot in it is transparent (the hole). Returns RGBA uint8 (H, W, 4).
    """
    from PIL import Image, ImageDraw

    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    sky_top, sky_low = np.array([70, 130, 200]), np.array([190, 220, 245])
    u = (y / (height - 1))[..., None]
    rgb = sky_top * (1 - u) + sky_low * u
    hill = height * 0.62 + 18 * np.sin(x / width * 2.6 * np.pi + 0.4)
    ground = y > hill
    rgb[ground] = np.array([90, 160, 80]) * 0.85 + 0.15 * np.array([60, 110, 40]) * (
        (x[ground] // 8 + y[ground] // 8) % 2)[..., None]
    image = Image.fromarray(rgb.round().astype(np.uint8), "RGB").convert("RGBA")
    draw = ImageDraw.Draw(image)
    for gx in range(0, width, 16):
        draw.line([(gx, 0), (gx, height - 1)], fill=(255, 255, 255, 255), width=1)
    for gy in range(0, height, 16):
        draw.line([(0, gy), (width - 1, gy)], fill=(255, 255, 255, 255), width=1)
    sun = (0.25 * width, 0.28 * height, 0.09 * width)
    draw.ellipse([sun[0] - sun[2], sun[1] - sun[2], sun[0] + sun[2], sun[1] + sun[2]],
                 fill=(250, 200, 40, 255), outline=(200, 120, 20, 255), width=3)
    curve = _still_curve(width, height)[0]
    draw.line([tuple(p) for p in curve], fill=(200, 30, 40, 255), width=4, joint="curve")
    picture = np.array(image)
    x0, x1, y0, y1 = _still_slot(width, height)
    picture[y0:y1, x0:x1] = 0  # the hole: transparent, and cut from the continuity matte
    return picture


def _still_slot(width: int, height: int) -> tuple[int, int, int, int]:
    return (int(0.60 * width), int(0.64 * width), int(0.15 * height), int(0.85 * height))


def _still_curve(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """(rest, pose) control points of the still demo's spline, left of the slot."""
    xs = np.linspace(0.08 * width, 0.55 * width, 5)
    rest = np.stack([xs, 0.62 * height + 10 * np.sin(xs / width * 9)], axis=1)
    lift = np.array([0.0, 0.7, 1.0, 0.7, 0.0]) * -0.18 * height
    pose = rest + np.stack([np.zeros(5), lift], axis=1)
    return rest.round(1), pose.round(1)


def still_scene(width: int = STILL_SIZE[0], height: int = STILL_SIZE[1]) -> dict[str, Any]:
    """The still demo's scene (images ``before.png`` and ``matte.png`` beside it).

    At t = 0 the drawing is at rest; at t = 1 the red curve is lifted into an arch, the
    point right of the slot is pulled to the right and down, and the picture's border is
    held. The slot is a hole in the continuity matte, so the arch does not drag the picture
    across it.
    """
    rest, pose = _still_curve(width, height)
    point = [0.82 * width, 0.45 * height]
    w, h = width - 1, height - 1
    return {
        "inkwarp": 1, "width": width, "height": height, "fps": 1, "duration": 1.0,
        "background": [255, 255, 255, 255],
        "layers": [{"name": "picture", "image": "before.png", "continuity": "matte.png"}],
        "features": [
            {"id": "curve", "kind": "spline", "rest": rest.tolist(),
             "keys": [{"t": 1.0, "points": pose.tolist()}]},
            {"id": "point", "kind": "point", "rest": [point],
             "keys": [{"t": 1.0, "points": [[point[0] + 0.06 * width, point[1] + 0.1 * height]]}]},
            {"id": "border", "kind": "polyline", "closed": True,
             "rest": [[0, 0], [w, 0], [w, h], [0, h]]},
        ],
    }


def stills(out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write the still demo into ``out_dir``: before.png, matte.png, after.png, field.png."""
    import inkwarp
    from inkwarp import video

    out = Path(out_dir)
    picture = still_picture()
    matte = np.where(picture[..., 3:4] > 0, 255, 0).astype(np.uint8).repeat(3, axis=2)
    paths = []
    for name, frame in (("before.png", picture), ("matte.png", matte)):
        paths += video.write_frames(out / name, [frame], fps=1)
    scene = inkwarp.Scene.from_dict(still_scene(), base_dir=str(out))
    paths += video.write_frames(out / "after.png", [scene.render(time=1.0)], fps=1)
    field = scene.field(time=1.0)
    paths += video.write_frames(out / "field.png", [video.field_picture(field)], fps=1)
    return paths
