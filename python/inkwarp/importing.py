"""Starting a scene from a picture: a PNG, JPEG or WebP gives one layer, a layered PSD one
layer per pixel layer.

A PSD's layers keep their order (the bottom layer first, as scene layers go back to front),
their names, their visibility and their position: every layer becomes a canvas-sized image
with the layer's pixels where the PSD puts them (a scene's images all have the frame's size,
so the drawing traced over the composite lines up with every layer, and each layer's
``offset`` stays ``[0, 0]`` for the animator to use). A layer's opacity is multiplied into
its alpha. Groups are flattened into their layers (a group's opacity and visibility pass on
to the layers in it); a layer clipped to the one below (a clipping mask) is cut to that
layer's shape and stays a layer of its own; a layer or group whose blend mode is not Normal
(or Pass Through, for a group) is kept but reported, because inkwarp composites every layer
with "over".

Examples
--------
>>> import numpy as np, os, tempfile
>>> from PIL import Image
>>> folder = tempfile.mkdtemp()
>>> art = np.zeros((24, 32, 4), np.uint8); art[4:20, 8:24] = (200, 40, 40, 255)
>>> Image.fromarray(art).save(os.path.join(folder, "square.png"))
>>> picture = read_picture(os.path.join(folder, "square.png"))
>>> (picture.width, picture.height), [layer.name for layer in picture.layers]
((32, 24), ['square'])
"""

from __future__ import annotations

import io
import json
import os
import re
import unicodedata
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp._atomic import temp_path
from inkwarp.errors import InkwarpWarning, InputError, MissingFileError

__all__ = ["Picture", "PictureLayer", "read_picture", "scene_dict", "write_new_scene"]

#: Suffixes of flat pictures (one layer). Their contents decide: PNG and JPEG, which the
#: engine decodes itself, a scene points at where they are; WebP is converted to a PNG.
FLAT_SUFFIXES = (".png", ".jpg", ".jpeg", ".jfif", ".jpe", ".webp")


@dataclass
class PictureLayer:
    """One layer of a picture: a canvas-sized RGBA image (straight alpha)."""

    name: str
    image: np.ndarray
    visible: bool = True
    #: The file the layer's pixels can be read from unchanged (a flat PNG or JPEG), if any.
    source: Path | None = None


@dataclass
class Picture:
    """A picture read for a new scene: its canvas size, its layers (back to front) and
    the notes made while reading it (flattened groups, unusual blend modes)."""

    width: int
    height: int
    layers: list[PictureLayer]
    notes: list[str] = field(default_factory=list)


def read_picture(path: str | os.PathLike[str]) -> Picture:
    """Reads a PNG, JPEG, WebP or PSD file as the layers of a new scene.

    Parameters
    ----------
    path : path
        The picture. ``.psd`` files are read with psd-tools (``pip install psd-tools``);
        they must be in RGB colour mode with 8 bits per channel.

    Returns
    -------
    Picture

    Raises
    ------
    inkwarp.errors.MissingFileError
        When there is no such file.
    ValueError
        When the file cannot be read, naming the file and what to do.
    """
    source = Path(os.fspath(path))
    if not source.exists():
        raise MissingFileError(2, "No such file or directory", str(source))
    if source.is_dir():
        raise IsADirectoryError(21, "is a directory, not a picture", str(source))
    suffix = source.suffix.lower()
    with open(source, "rb") as file:
        start = file.read(64)
    if not start:
        raise InputError(f"{source}: the file is empty (0 bytes: a save, copy or download that did not "
                         "finish?); save or copy it again")
    # By its contents, as a flat picture is: a Photoshop document under another name is one.
    if suffix == ".psd" or start.startswith(b"8BPS"):
        return _read_psd(source)
    if suffix in FLAT_SUFFIXES:
        return _read_flat(source)
    from inkwarp.scene import _video_kind

    video = _video_kind(start)
    if video:
        raise InputError(f"{source}: {'an' if video in ('MP4', 'AVI') else 'a'} {video} video, not a picture; "
                         f"take the frame to trace from it (inkwarp frame {source} --frame 0 -o frame.png) and "
                         f"start the scene from that (inkwarp new frame.png -o scene.json): inkwarp track {source} "
                         "--scene scene.json then follows the drawing through the video")
    raise InputError(f"{source}: cannot start a scene from '{suffix or 'no suffix'}' files; "
                     "give a PNG, JPEG, WebP or layered PSD picture")


def _check_size(source: Path, size: tuple[int, int] | None) -> None:
    """Refuse a picture over the most pixels inkwarp handles, naming it, before it is
    decoded; ``size`` None: one Pillow found far over it."""
    from inkwarp._inkwarp import MAX_PIXELS

    if size is None or size[0] * size[1] > MAX_PIXELS:
        what = f"is {size[0]}×{size[1]} pixels," if size is not None else "has"
        raise InputError(f"{source}: the picture {what} more than the {MAX_PIXELS >> 20} megapixels inkwarp "
                         "handles; scale it down first")


def _read_flat(source: Path) -> Picture:
    from PIL import Image, UnidentifiedImageError

    from inkwarp.imaging import rgba_pixels, upright

    def unreadable(err: BaseException) -> ValueError:
        return ValueError(f"{source}: not a readable {source.suffix.lstrip('.').upper()} "
                          f"picture ({err}); export it again from the painting app")

    try:
        # Pillow's own guard (a warning past 89 megapixels, an error past twice that) speaks
        # of attacks; the size is checked against inkwarp's limit before decoding.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(source)
    except Image.DecompressionBombError:
        _check_size(source, None)
        raise  # (not reached: the size is refused)
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as err:
        raise unreadable(err) from None
    with image:
        _check_size(source, image.size)
        # By its contents, not its name (a browser saves WebP as .jpg): PNG and JPEG (a phone's
        # multi-picture JPEG too) the scene keeps as they are, decoded as the engine decodes
        # them (its EXIF orientation rule included); WebP is converted to a PNG beside the scene.
        kind = image.format
        if kind not in ("PNG", "JPEG", "MPO", "WEBP"):
            raise InputError(f"{source}: a {kind or 'unknown'} picture under a {source.suffix or 'bare'} name; "
                             "inkwarp reads PNG, JPEG and WebP: save it as one of those")
        # The engine reads no colour profile: a picture in another space than sRGB (a phone's
        # Display P3) is converted here, as a viewer shows it, into a PNG beside the scene.
        profile, notes = _foreign_profile(image), []
        try:
            if kind == "WEBP" or profile is not None:
                image.load()
                shown = upright(image)
                if profile is not None:
                    shown, said = _to_srgb(shown, *profile)
                    notes.append(f"{source}: {said}")
                rgba = rgba_pixels(shown)
            else:
                from inkwarp import _inkwarp

                rgba = _inkwarp.decode_picture(source.read_bytes())
        except (OSError, SyntaxError, ValueError) as err:
            raise unreadable(err) from None
    height, width = rgba.shape[:2]
    kept = None if kind == "WEBP" or profile is not None else source
    return Picture(width, height, [PictureLayer(source.stem, rgba, True, kept)], notes)


def _foreign_profile(image: Any) -> tuple[Any, str | None] | None:
    """The ICC profile of an RGB(A) Pillow image where it is not sRGB's, read, with its
    description (where it cannot be read: why, and None); else None."""
    from PIL import ImageCms

    icc = image.info.get("icc_profile")
    if not icc or image.mode not in ("RGB", "RGBA"):
        return None
    try:
        profile = ImageCms.ImageCmsProfile(io.BytesIO(icc))
        name = ImageCms.getProfileDescription(profile).strip() or "unnamed"
    except (OSError, ValueError, TypeError, ImageCms.PyCMSError) as err:
        return " ".join(str(err).split()), None
    return None if "srgb" in name.lower() else (profile, name)


def _to_srgb(image: Any, profile: Any, name: str | None) -> tuple[Any, str]:
    """``image`` converted from ``profile`` (see :func:`_foreign_profile`) to sRGB (alpha
    kept), and what was done."""
    from PIL import Image, ImageCms

    unreadable = lambda why: (image, f"its colour profile cannot be read ({why}); its colours are taken as "  # noqa: E731
                              "sRGB, which may shift them: convert it to sRGB in the painting app")
    if name is None:
        return unreadable(profile)
    try:
        rgb = ImageCms.profileToProfile(image.convert("RGB"), profile, ImageCms.createProfile("sRGB"),
                                        renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC, outputMode="RGB")
    except (OSError, ValueError, TypeError, ImageCms.PyCMSError) as err:
        return unreadable(" ".join(str(err).split()))
    if image.mode == "RGBA":
        rgb.putalpha(image.getchannel("A"))
    return (rgb if isinstance(rgb, Image.Image) else image,
            f"converted from its colour profile ({name}) to sRGB, the colours inkwarp renders in, "
            "into a PNG beside the scene")


def _read_psd(source: Path) -> Picture:
    try:
        from psd_tools import PSDImage
        from psd_tools.constants import BlendMode, ColorMode
    except ImportError:  # pragma: no cover - psd-tools is a dependency
        raise InputError(f"{source}: reading PSD files needs psd-tools; "
                         "install it with 'pip install psd-tools'") from None
    start: bytes | None = None  # unreadable: said below, as psd-tools meets it
    try:
        with open(source, "rb") as fh:
            start = fh.read(8)
    except OSError:
        pass
    if start is not None and not start.startswith(b"8BPS"):  # every Photoshop document starts so
        named = {b"\x89PNG": ("a PNG picture", ".png"), b"\xff\xd8\xff": ("a JPEG picture", ".jpg")}
        found = next((kind for sig, kind in named.items() if start.startswith(sig)), None)
        if found:
            raise InputError(f"{source}: is {found[0]} under a .psd name; rename it to "
                             f"{source.with_suffix(found[1]).name}")
        raise InputError(f"{source}: not a PSD file (it does not start as one does); save it from "
                         "the painting app as a Photoshop document (RGB, 8 bits), or give a PNG or JPEG")
    try:
        psd = PSDImage.open(source)
    except Exception as err:  # noqa: BLE001 - psd-tools raises many kinds on a broken file
        size, needs = source.stat().st_size, _psd_layers_end(source)
        if needs is not None and size < needs:
            raise InputError(f"{source}: the file is cut short ({size:,} bytes, where its layers "
                             f"need {needs:,}: a copy or download that did not finish?); copy it "
                             "again, or save it again from the painting app") from None
        reason = " ".join(str(err).split()) or type(err).__name__
        raise InputError(f"{source}: not a readable PSD file ({reason}); save it again from "
                         "the painting app as a Photoshop document (RGB, 8 bits)") from None
    _check_size(source, (psd.width, psd.height))
    if psd.color_mode != ColorMode.RGB:
        mode = getattr(psd.color_mode, "name", str(psd.color_mode))
        raise InputError(f"{source}: the PSD is in {mode} colour mode; inkwarp reads RGB "
                         "documents: convert it (Photoshop: Image > Mode > RGB Color) and "
                         "save it again")
    if psd.depth != 8:
        raise InputError(f"{source}: the PSD has {psd.depth} bits per channel; inkwarp reads "
                         "8-bit documents: convert it (Photoshop: Image > Mode > 8 Bits/Channel)"
                         " and save it again")
    width, height = int(psd.width), int(psd.height)
    notes: list[str] = []
    layers: list[PictureLayer] = []
    normal = {BlendMode.NORMAL, BlendMode.PASS_THROUGH}

    def named(here: list[str]) -> str:  # its own name (groups are flattened, names kept), its group beside
        return f"'{here[-1]}'" + (f" (in group '{' / '.join(here[:-1])}')" if len(here) > 1 else "")

    def walk(group: Iterable[Any], path: list[str], opacity: float, visible: bool) -> None:
        # The layers the last unclipped item of this group gave (its base for the clipped
        # layers above it), its name and whether it shows.
        base: tuple[int, int, str, bool] | None = None
        for layer in group:
            name = str(layer.name)
            here = [*path, name]
            shown = visible and bool(layer.visible)
            first = len(layers)
            clipped = base is not None and _clipped(layer)
            if clipped and not base[3]:
                shown = False  # a hidden base hides what is clipped to it
            walk_one(layer, here, opacity, shown)
            if clipped:
                _clip(layers[first:], layers[base[0]:base[1]])
                notes.append(f"{source}: {'group' if layer.is_group() else 'layer'} "
                             f"{named(here)} is clipped to '{base[2]}': it is cut to "
                             "that layer's shape as the PSD shows it, and stays a layer of its own")
            else:
                base = (first, len(layers), name, shown)

    def walk_one(layer: Any, here: list[str], opacity: float, shown: bool) -> None:
        alpha = opacity * int(layer.opacity) / 255.0
        if layer.blend_mode not in normal:
            mode = getattr(layer.blend_mode, "name", str(layer.blend_mode))
            kind = "group" if layer.is_group() else "layer"
            hidden = "" if shown else " (hidden now)"
            notes.append(f"{source}: {kind} {named(here)}{hidden} uses the blend mode "
                         f"{mode.replace('_', ' ').title()}; inkwarp composites it as "
                         "Normal, so it will look different: merge it into the layer "
                         "below or set it to Normal")
        if layer.is_group():
            # At full opacity nothing of the group shows differently; below it, each layer is
            # faded alone, so where they overlap the lower ones show through.
            faded = (f"its opacity ({round(100 * int(layer.opacity) / 255)} %) and visibility applied to "
                     "each of them, which shows where they overlap") if int(layer.opacity) < 255 else \
                "its visibility applied to each of them"
            notes.append(f"{source}: group {named(here)} is flattened into its layers (names kept, {faded})")
            walk(layer, here, alpha, shown)
            return
        try:
            image = layer.topil()
        except Exception as err:  # noqa: BLE001 - a damaged layer record
            raise InputError(f"{source}: layer {named(here)} cannot be read ({err}); "
                             "save the PSD again from the painting app") from None
        if image is None:  # an empty layer, or an adjustment or fill layer without pixels
            if layer.kind not in ("pixel", "type", "shape", "smartobject"):
                notes.append(f"{source}: layer {named(here)} ({layer.kind}) has no "
                             "pixels and is left out; rasterise it to keep it")
                return
            image = None
        if layer.kind != "pixel" and image is not None:
            notes.append(f"{source}: layer {named(here)} ({layer.kind}) is taken as "
                         "the pixels the PSD stores for it")
        canvas = np.zeros((height, width, 4), np.uint8)
        if image is not None:
            rgba = np.asarray(image.convert("RGBA"))
            _paste(canvas, rgba, int(layer.left), int(layer.top))
            if rgba[..., 3].any() and not canvas[..., 3].any():
                notes.append(f"{source}: layer {named(here)} lies wholly off the {width}x{height} canvas "
                             f"(its box at x {int(layer.left)}, y {int(layer.top)}), so it comes in empty; "
                             "move it onto the canvas to keep it")
        mask = layer.mask if layer.has_mask() else None
        if mask is not None and not mask.disabled:
            # A layer mask (psd-tools keeps a layer's transparency in one too) scales
            # the alpha; outside its box it is its background colour.
            matte = np.full((height, width), int(mask.background_color), np.uint8)
            pixels = mask.topil()
            if pixels is not None:
                grey = np.asarray(pixels.convert("L"))[..., None]
                holder = np.repeat(matte[..., None], 4, axis=2)
                _paste(holder, np.repeat(grey, 4, axis=2), int(mask.left), int(mask.top))
                matte = holder[..., 0]
            canvas[..., 3] = (canvas[..., 3].astype(np.uint16) * matte // 255).astype(np.uint8)
        if alpha < 1.0:
            canvas[..., 3] = np.round(canvas[..., 3] * alpha).astype(np.uint8)
        layers.append(PictureLayer(here[-1], canvas, shown))

    walk(psd, [], 1.0, True)
    if not layers:
        raise InputError(f"{source}: the PSD has no pixel layers; add a layer with the picture "
                         "and save it again")
    return Picture(width, height, layers, notes)


def _psd_layers_end(source: Path) -> int | None:
    """Where a PSD's layer section ends by the lengths its sections declare (the header,
    colour mode data, image resources, then layers and masks), or None where the file is
    too short or odd to tell."""
    try:
        with open(source, "rb") as fh:
            head = fh.read(26)
            if len(head) < 26 or head[4:6] not in (b"\x00\x01", b"\x00\x02"):
                return None
            at = 26
            for width in (4, 4, 8 if head[4:6] == b"\x00\x02" else 4):
                fh.seek(at)
                field = fh.read(width)
                if len(field) < width:
                    return at + width
                at += width + int.from_bytes(field, "big")
            return at
    except OSError:
        return None


def _clipped(layer: Any) -> bool:
    """Whether a PSD layer is clipped to the one below it (psd-tools renamed the flag)."""
    flag = getattr(type(layer), "clipping", None)
    return bool(layer.clipping if isinstance(flag, property) else layer.clipping_layer)


def _clip(clipped: list[PictureLayer], base: list[PictureLayer]) -> None:
    """Cuts ``clipped`` to the shape of ``base``: their alphas scaled by the alpha of the
    base's layers composited "over" one another (a group's, where the base is a group)."""
    if not clipped:
        return
    clear = np.ones(clipped[0].image.shape[:2])
    # A hidden layer of a base group shapes nothing (all of a hidden base's do: shown again,
    # it shapes what is clipped to it).
    shown = [layer for layer in base if layer.visible] or base
    for layer in shown:
        clear *= 1.0 - layer.image[..., 3] / 255.0
    for layer in clipped:
        layer.image[..., 3] = np.round(layer.image[..., 3] * (1.0 - clear)).astype(np.uint8)


def _paste(canvas: np.ndarray, image: np.ndarray, left: int, top: int) -> None:
    """``image`` placed with its top-left pixel at ``(left, top)`` of ``canvas``, clipped."""
    height, width = canvas.shape[:2]
    h, w = image.shape[:2]
    x0, y0 = max(left, 0), max(top, 0)
    x1, y1 = min(left + w, width), min(top + h, height)
    if x0 < x1 and y0 < y1:
        canvas[y0:y1, x0:x1] = image[y0 - top:y1 - top, x0 - left:x1 - left]


def _unique_names(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for name in names:
        base = name.strip() or "layer"
        candidate = base
        while candidate in seen:
            seen[base] += 1
            candidate = f"{base} ({seen[base]})"
        seen.setdefault(candidate, 1)
        out.append(candidate)
    return out


#: Letters with no decomposition into a base letter and an accent, spelled in ASCII.
_LETTERS = str.maketrans({"ß": "ss", "Œ": "OE", "œ": "oe", "Æ": "AE", "æ": "ae", "Ø": "O", "ø": "o",
                          "Ł": "L", "ł": "l", "Đ": "D", "đ": "d", "Þ": "Th", "þ": "th", "ı": "i"})


def _slug(name: str) -> str:
    """A layer's name as part of a file name: safe characters only, and short (a PSD layer
    name may be 255 characters, more than a file name may hold with the scene's name).
    Accented letters keep their base letter ("Ébauche" → "Ebauche")."""
    spelled = name.translate(_LETTERS)
    plain = "".join(c for c in unicodedata.normalize("NFKD", spelled) if not unicodedata.combining(c))
    return re.sub(r"[^A-Za-z0-9._-]+", "-", plain).strip("-.")[:64].strip("-.") or "layer"


def scene_dict(picture: Picture, images: list[str], *, fps: float = 24.0,
               duration: float = 2.0, features: list[dict[str, Any]] | None = None
               ) -> dict[str, Any]:
    """The scene of a picture whose layers' images are at ``images`` (paths or data URIs).

    The background is transparent (alpha 0), so frame 0 of the scene is the picture's
    composite, transparency included. Every layer holds its border, as a picture opened in
    the editor does: a drawing pulled near the edge does not drag the frame's edge along.
    """
    names = _unique_names([layer.name for layer in picture.layers])
    layers: list[dict[str, Any]] = []
    for name, layer, image in zip(names, picture.layers, images):
        entry: dict[str, Any] = {"name": name, "image": image, "border": "hold"}
        if not layer.visible:
            entry["visible"] = False
        layers.append(entry)
    return {
        "inkwarp": 1,
        "width": picture.width,
        "height": picture.height,
        "fps": fps,
        "duration": duration,
        "background": [255, 255, 255, 0],
        "layers": layers,
        "features": list(features or []),
    }


def _encode_png(image: np.ndarray) -> bytes:
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image), "RGBA").save(buffer, format="PNG")
    return buffer.getvalue()


def _picture_and_drawing(picture_path: str | os.PathLike[str], drawing: str | os.PathLike[str] | None
                         ) -> tuple[Picture, list[dict[str, Any]], list[str]]:
    """The picture, the features of the SVG drawing traced over it (none without one) and
    the notes about both."""
    from inkwarp.svg import read_drawing

    picture = read_picture(picture_path)
    notes = list(picture.notes)
    features: list[dict[str, Any]] = []
    if drawing is not None:
        features, drawing_notes = read_drawing(drawing, picture.width, picture.height)
        notes += drawing_notes
    return picture, features, notes


def write_new_scene(picture_path: str | os.PathLike[str], output: str | os.PathLike[str], *,
                    drawing: str | os.PathLike[str] | None = None, embed: bool = False,
                    fps: float = 24.0, duration: float = 2.0,
                    force: bool = False) -> tuple[list[Path], list[str]]:
    """Writes a new scene for a picture (and optionally an SVG drawing traced over it).

    The layers' images go beside the scene as ``SCENE-LAYER.png`` (a flat PNG or JPEG is
    referred to where it is instead), or into the scene as ``data:`` URIs with ``embed``.
    Everything is checked (the scene is built by the engine) before anything is written,
    and every file is written under a temporary name and renamed at the end, so a failure
    leaves nothing behind. A scene or layer image that already exists is an error (a day's
    tracing is not replaced by a fresh scene by mistake) unless ``force`` is set.

    Returns
    -------
    (paths, notes)
        The files written (the scene last) and the notes about the picture and drawing.
    """
    from inkwarp.scene import Scene

    target = Path(os.fspath(output))
    if target.suffix.lower() != ".json":
        raise InputError(f"{target}: name the scene file .json, such as {target.with_suffix('.json').name}")
    from inkwarp.video import check_file

    check_file(target, ".json")
    folder = target.absolute().parent
    picture, features, notes = _picture_and_drawing(picture_path, drawing)
    encoded = [_encode_png(layer.image) for layer in picture.layers]
    import base64

    uris = ["data:image/png;base64," + base64.b64encode(data).decode("ascii") for data in encoded]
    data = scene_dict(picture, uris, fps=fps, duration=duration, features=features)
    Scene.from_dict(data)  # every problem, raised as a SceneError, before anything is written

    files: list[tuple[Path, bytes]] = []
    if not embed:
        names = [layer["name"] for layer in data["layers"]]
        used: set[str] = set()
        for index, (name, layer, png) in enumerate(zip(names, picture.layers, encoded)):
            if layer.source is not None:
                reference = Path(os.path.relpath(layer.source.absolute(), folder)).as_posix()
            else:
                # Different names can share a slug ("a b", "a-b"); a case-insensitive
                # file system also takes "Arm" for "arm".
                file_name = f"{target.stem}-{_slug(name)}.png"
                suffix = 2  # the second of a name is -2, the third -3
                while file_name.casefold() in used:
                    file_name = f"{target.stem}-{_slug(name)}-{suffix}.png"
                    suffix += 1
                used.add(file_name.casefold())
                files.append((target.parent / file_name, png))
                reference = file_name
            data["layers"][index]["image"] = reference
    files.append((target, (json.dumps(data, indent=2) + "\n").encode("utf-8")))
    existing = [path for path, _ in files if path.exists()]
    if existing and not force:
        names = ", ".join(str(path) for path in existing)
        verb = "exists" if len(existing) == 1 else "exist"
        raise InputError(f"{names}: already {verb}; choose another scene name, or replace "
                         f"{'it' if len(existing) == 1 else 'them'} with --force (in Python, force=True)")
    left = _left_behind(target, data) if force else []
    _write_all(files)
    if left:
        it = "it" if len(left) == 1 else "them"
        notes.append(f"{target}: the scene it replaced used {', '.join(left)}, which the new one does not; "
                     f"left in place (delete {it} if nothing else uses {it})")
    return [path for path, _ in files], notes


def _left_behind(target: Path, data: dict[str, Any]) -> list[str]:
    """The layer images beside ``target`` that the scene there now refers to and ``data``
    (the scene replacing it) does not: a forced ``new`` leaves them, and says so."""
    try:
        old = json.loads(target.read_text(encoding="utf-8"))
        layers = old.get("layers") if isinstance(old, dict) else None
        given = [layer.get("image") for layer in layers if isinstance(layer, dict)] if isinstance(layers, list) else []
    except (OSError, ValueError):  # (an old scene that is no scene: nothing to name)
        return []

    def file(image: str) -> Path:
        return (target.parent / image).resolve()

    kept = {file(layer["image"]) for layer in data["layers"] if not layer["image"].startswith("data:")}
    return sorted({image for image in given if isinstance(image, str) and not image.startswith("data:")
                   and "\0" not in image and file(image).is_file() and file(image) not in kept})


def _write_all(files: list[tuple[Path, bytes]]) -> None:
    """Every file under a temporary name first, then all renamed; on any failure the
    temporary files are removed and no target is touched."""
    temps: list[Path] = []
    try:
        for path, content in files:
            temp = temp_path(path)
            temps.append(temp)
            temp.write_bytes(content)
        for temp, (path, _) in zip(temps, files):
            os.replace(temp, path)
    except BaseException:
        for temp in temps:
            temp.unlink(missing_ok=True)
        raise


def new_scene(picture_path: str | os.PathLike[str], *, drawing: str | os.PathLike[str] | None = None,
              fps: float = 24.0, duration: float = 2.0) -> dict[str, Any]:
    """The scene dict of a picture, its images as ``data:`` URIs; notes become warnings."""
    picture, features, notes = _picture_and_drawing(picture_path, drawing)
    for note in notes:
        warnings.warn(note, InkwarpWarning, stacklevel=3)
    import base64

    uris = ["data:image/png;base64," + base64.b64encode(_encode_png(layer.image)).decode("ascii")
            for layer in picture.layers]
    return scene_dict(picture, uris, fps=fps, duration=duration, features=features)
