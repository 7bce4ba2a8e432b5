"""Images in and out: the forward-mapping warp, and PNG reading and writing.

Images at this boundary are NumPy ``uint8`` arrays of shape ``(H, W, 4)``: straight (not
premultiplied) RGBA, row ``y``, column ``x``, with pixel centres at integer coordinates
(DESIGN §2).
"""

from __future__ import annotations

import os
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from inkwarp import _inkwarp
from inkwarp.errors import InputError, MissingFileError

__all__ = ["read_image", "warp_image", "write_png"]

PathLike = Union[str, "os.PathLike[str]"]


def _as_rgba(image: ArrayLike, name: str = "image", *, grey: bool = False, limit: bool = False) -> NDArray[np.uint8]:
    """``image`` as a C-contiguous ``(H, W, 4)`` uint8 array, RGB and (with ``grey``) grey
    ``(H, W)`` made opaque RGBA; with ``limit``, refused past inkwarp's largest picture
    before anything is copied."""
    shapes = "(H, W), (H, W, 3) or (H, W, 4)" if grey else "(H, W, 3) or (H, W, 4)"
    if isinstance(image, (bytes, bytearray)):
        raise InputError(f"{name} must be an {shapes} uint8 array, got {len(image)} bytes of a "
                         "file; decode them first, with inkwarp.imaging.read_image(io.BytesIO(data))")
    if isinstance(image, (str, os.PathLike)):
        raise InputError(f"{name} must be an {shapes} uint8 array, got the path {os.fspath(image)!r:.200}; "
                         "read the picture first, with inkwarp.imaging.read_image(path)")
    array = np.asarray(image)
    if array.dtype.kind not in "biuf":
        raise InputError(f"{name} must be an {shapes} uint8 array ({'grey, ' if grey else ''}RGB or RGBA), got "
                         f"{'None' if image is None else type(image).__name__ + ' of dtype ' + str(array.dtype)}")
    if array.dtype != np.uint8:
        # The fix for the values it holds: 16-bit levels, levels 0-255 already (integers, or
        # floats well past 1), or a float image in [0, 1] (a little past 1 after a filter).
        kind = array.dtype.kind
        numbers = kind in "iuf" and array.size > 0 and bool(np.isfinite(array).all())
        top = float(array.max()) if numbers else 0.0
        past = kind == "f" and top > 2
        if kind in "iu" and top > 255:
            fix = f"levels up to {top:.0f} (16-bit ones: 65535) with (image // 257).astype(np.uint8)"
        elif kind == "b":
            fix = "a mask with image.astype(np.uint8) * 255"
        elif kind in "iu" or past:
            fix = "levels 0-255 with np.clip(np.round(image), 0, 255).astype(np.uint8)"
        else:
            fix = "a float image in [0, 1] with (np.clip(image, 0, 1) * 255).round().astype(np.uint8)"
        raise InputError(f"{name} must be a uint8 array, got dtype {array.dtype}; convert {fix}")
    if not ((array.ndim == 3 and array.shape[2] in (3, 4)) or (grey and array.ndim == 2)):
        if array.ndim == 2:
            fix = "; make a grey image RGB with np.dstack([image] * 3)"
        elif array.ndim == 3 and array.shape[2] == 1:
            fix = ("; pass a grey image as (H, W): image[..., 0]" if grey
                   else "; make a grey image RGB with np.dstack([image[..., 0]] * 3)")
        elif array.ndim == 3 and array.shape[2] == 2:
            fix = "; make grey and alpha RGBA with np.dstack([image[..., 0]] * 3 + [image[..., 1]])"
        else:
            fix = ""
        raise InputError(
            f"{name} must have shape {shapes} ({'grey, ' if grey else ''}RGB or RGBA), got {array.shape}{fix}"
        )
    if limit:
        _inkwarp.check_size(name, array.shape[1], array.shape[0])
    if array.ndim == 2:
        array = array[..., None].repeat(3, axis=2)
    if array.shape[2] == 3:
        alpha = np.full(array.shape[:2] + (1,), 255, dtype=np.uint8)
        array = np.concatenate([array, alpha], axis=2)
    return np.ascontiguousarray(array)


def warp_image(
    image: ArrayLike, field: ArrayLike, matte: ArrayLike | None = None, cuts: Any = None
) -> NDArray[np.uint8]:
    """Warp an image by a displacement field, by forward mapping.

    Every pixel is a vertex of a mesh placed at its displaced position ``(x + Δx, y + Δy)``;
    every 2×2 block of pixels that the matte connects is a quad, shaded by bilinear
    interpolation of its four pixels' premultiplied colours, with exact (analytic) coverage
    at the edges of each piece. Pixels the matte separates come apart where the field pulls
    them apart. See ``docs/concepts/forward-mapping.md`` for the exact rules.

    Parameters
    ----------
    image : array_like of uint8, shape (H, W), (H, W, 3) or (H, W, 4)
        The picture: grey or RGB (both made opaque RGBA, as a scene reads a grey PNG), or
        straight RGBA. At most 32768 pixels a side and 64 megapixels, as for every picture
        inkwarp takes. Grey with alpha, ``(H, W, 2)``, is refused: make it RGBA with
        ``np.dstack([image[..., 0]] * 3 + [image[..., 1]])``.
    field : array_like of float, shape (H, W, 2)
        The displacement of every pixel in pixels: ``field[y, x] = (Δx, Δy)``, such as
        :func:`inkwarp.thin_plate` returns. Converted to float32.
    matte : array_like, shape (H, W), optional
        The continuity matte: nonzero pixels are connected to their nonzero 4-neighbours.
        Default: the image's alpha > 0. Pixels outside the matte that are visible are still
        drawn, each on its own.
    cuts : list of array_like, each shape (K, 2), optional
        Polylines in pixel coordinates, as :func:`inkwarp.thin_plate` takes them: two
        pixels whose link a cut crosses are not connected, so the picture tears there
        where the field pulls the sides apart. Pass the cuts the field was solved with.

    Returns
    -------
    numpy.ndarray of uint8, shape (H, W, 4)
        The warped image, straight RGBA, on a transparent background of the same size.
        Fully transparent pixels are ``(0, 0, 0, 0)``.

    Raises
    ------
    ValueError
        If a shape or dtype is wrong, the image is larger than inkwarp handles, or the
        field holds NaN or infinity.

    Notes
    -----
    The identity field reproduces the image exactly (fully transparent pixels come back
    as ``(0, 0, 0, 0)``), and an integer translation shifts it exactly. The computation runs
    without the GIL, on all cores.

    Examples
    --------
    >>> import numpy as np
    >>> import inkwarp
    >>> image = np.zeros((4, 6, 3), np.uint8)
    >>> image[:, :3] = (255, 0, 0)          # red left half, black right half
    >>> field = np.zeros((4, 6, 2), np.float32)
    >>> field[..., 0] = 1.0                 # everything moves one pixel right
    >>> out = inkwarp.warp_image(image, field)
    >>> out.shape, out.dtype
    ((4, 6, 4), dtype('uint8'))
    >>> out[0, :, 0].tolist()               # red channel of the first row
    [0, 255, 255, 255, 0, 0]
    >>> out[0, :, 3].tolist()               # the first column is uncovered
    [0, 255, 255, 255, 255, 255]
    """
    rgba = _as_rgba(image, grey=True, limit=True)
    height, width = rgba.shape[:2]

    array = np.asarray(field)
    if array.dtype.kind not in "fiu":
        raise InputError(
            f"field must be a real numeric array (float32 preferred), got dtype {array.dtype}"
        )
    if array.shape != (height, width, 2):
        raise InputError(
            f"field must have shape (H, W, 2) = ({height}, {width}, 2) to match the image, "
            f"got {array.shape}"
        )
    displacement = np.ascontiguousarray(array, dtype=np.float32)
    if not np.isfinite(displacement).all():
        bad = np.argwhere(~np.isfinite(displacement).all(axis=2))[0]
        raise InputError(
            f"field must be finite, but holds NaN or infinity (first at row {bad[0]}, "
            f"column {bad[1]})"
        )

    if matte is None:
        connected = (rgba[..., 3] > 0).astype(np.uint8)
    else:
        from inkwarp.plate import _mask_u8

        connected = _mask_u8(matte, height, width, "matte")

    from inkwarp.plate import _cuts

    return _inkwarp.warp_image(rgba, displacement, connected, _cuts(cuts))


def read_image(path: PathLike) -> NDArray[np.uint8]:
    """Read an image file as straight RGBA.

    Parameters
    ----------
    path : str or os.PathLike
        Any format Pillow reads (PNG, JPEG, ...); PNG and JPEG are decoded by the engine,
        exactly as a scene's pictures are. Grey, palette and RGB images are converted;
        images without alpha come back opaque. A photograph tagged with an EXIF orientation
        comes back upright, as scenes read it.

    Returns
    -------
    numpy.ndarray of uint8, shape (H, W, 4)

    Raises
    ------
    inkwarp.errors.MissingFileError
        If there is no such file.
    ValueError
        If the file is not an image Pillow can read.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from inkwarp.imaging import read_image, write_png
    >>> path = os.path.join(tempfile.mkdtemp(), "dot.png")
    >>> write_png(path, np.full((2, 3, 4), (10, 20, 30, 255), np.uint8))
    >>> read_image(path)[1, 2].tolist()
    [10, 20, 30, 255]
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            if im.format not in ("PNG", "JPEG", "MPO"):
                return rgba_pixels(upright(im))
    except UnidentifiedImageError as e:
        raise InputError(f"{os.fspath(path)} is not an image that can be read: {e}") from None
    except FileNotFoundError as e:
        raise MissingFileError(e.errno, e.strerror, os.fspath(path)) from None
    # PNG and JPEG as the engine decodes them: the same pixels and orientation as a scene's.
    try:
        with open(path, "rb") as file:
            return _inkwarp.decode_picture(file.read())
    except ValueError as e:
        raise InputError(f"{os.fspath(path)} is not an image that can be read: {e}") from None


def upright(image: Any) -> Any:
    """A Pillow image turned upright by the orientation in its EXIF block (a JPEG's APP1, a
    PNG's eXIf chunk), as viewers show it; an orientation written elsewhere (XMP, a PNG text
    chunk) is not read. For the pictures other than PNG and JPEG (the engine decodes those
    itself, reading an Orientation only where it is stored as a SHORT, and a PNG's eXIf only
    before its pixels: :func:`read_image`)."""
    from PIL import Image

    raw = image.info.get("exif")
    if not raw:
        return image
    exif = Image.Exif()
    exif.load(raw)
    turn = {2: Image.Transpose.FLIP_LEFT_RIGHT, 3: Image.Transpose.ROTATE_180, 4: Image.Transpose.FLIP_TOP_BOTTOM,
            5: Image.Transpose.TRANSPOSE, 6: Image.Transpose.ROTATE_270, 7: Image.Transpose.TRANSVERSE,
            8: Image.Transpose.ROTATE_90}.get(exif.get(0x0112))
    return image.transpose(turn) if turn else image


def rgba_pixels(image: Any) -> NDArray[np.uint8]:
    """A Pillow image's pixels as straight RGBA ``uint8``, as the engine decodes them.

    Greyscale of more than 8 bits (Pillow's modes ``I;16``, ``I;16B``, ``I;16L`` and ``I``,
    in which some Pillow versions and formats hold 16-bit grey; levels taken as 0 to 65535)
    is rounded to 8 bits as the engine rounds 16-bit pictures, ``(v + 128) // 257``, but
    never a faint nonzero level to 0; a PNG's transparent grey level is made transparent.
    Pillow's own ``convert("RGBA")`` clips those levels to 255, turning the picture white.
    Every other mode is converted by Pillow (16-bit RGB, RGBA and grey with alpha, which
    Pillow reads as 8-bit RGB or RGBA, keep their high bytes).
    """
    if image.mode == "I" or image.mode.startswith("I;16"):
        levels = np.clip(np.asarray(image).astype(np.int64), 0, 65535)
        grey = np.maximum((levels + 128) // 257, levels > 0).astype(np.uint8)
        rgba = np.empty(grey.shape + (4,), np.uint8)
        rgba[..., :3] = grey[..., None]
        transparent = image.info.get("transparency")
        rgba[..., 3] = 255
        if isinstance(transparent, int):
            rgba[..., 3][levels == transparent] = 0
        return rgba
    return np.asarray(image.convert("RGBA"), dtype=np.uint8).copy()


#: zlib level of every PNG inkwarp writes. Level 1 writes a 12-megapixel photograph's frame
#: about four times faster than Pillow's default 6, for a file about 15 % larger (the
#: level OpenCV's ``imwrite`` uses by default too); any reader decodes either.
PNG_COMPRESS_LEVEL = 1


def write_png(path: PathLike, image: ArrayLike) -> None:
    """Write an image as PNG, atomically.

    The file is written under a temporary name in the same directory and then renamed,
    so ``path`` is either the complete new image or untouched, never half-written.

    Parameters
    ----------
    path : str or os.PathLike
        The PNG file to write (replaced if it exists).
    image : array_like of uint8, shape (H, W, 3) or (H, W, 4)
        RGB or straight RGBA.

    Raises
    ------
    ValueError
        If the image has the wrong shape or dtype.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from inkwarp.imaging import write_png
    >>> path = os.path.join(tempfile.mkdtemp(), "black.png")
    >>> write_png(path, np.zeros((8, 8, 3), np.uint8))
    >>> os.path.getsize(path) > 0
    True
    """
    from PIL import Image

    rgba = _as_rgba(image)
    target = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(target))
    base = os.path.basename(target)
    # A fresh name carrying the process id, permissions from the umask as for any new file.
    from inkwarp._atomic import temp_path

    temporary = os.fspath(temp_path(os.path.join(directory, base), ".png"))
    try:
        with open(temporary, "wb") as f:
            Image.fromarray(rgba).save(f, format="PNG", compress_level=PNG_COMPRESS_LEVEL)
        os.replace(temporary, target)
    except BaseException:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise
