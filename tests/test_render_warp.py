"""inkwarp.warp_image: the forward-mapping renderer through the Python API."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import inkwarp


def canonical(rgba):
    """Fully transparent pixels carry no colour."""
    out = rgba.copy()
    out[out[..., 3] == 0] = 0
    return out


def random_rgba(rng, h, w, holes=True):
    image = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    if holes:
        image[rng.random((h, w)) < 0.15, 3] = 0
        image[rng.random((h, w)) < 0.5, 3] = 255
    else:
        image[..., 3] = 255
    return canonical(image)


def constant_field(h, w, tx, ty):
    field = np.empty((h, w, 2), np.float32)
    field[..., 0] = tx
    field[..., 1] = ty
    return field


def box_translate(image, tx, ty, pad):
    """Exact area-weighted image of `image` translated by (tx, ty) onto a canvas enlarged by
    `pad` on every side, each source pixel a unit square of constant premultiplied colour."""
    h, w = image.shape[:2]
    alpha = image[..., 3:4].astype(np.float64) / 255.0
    premult = np.concatenate([image[..., :3] / 255.0 * alpha, alpha], axis=2)
    out = np.zeros((h + 2 * pad, w + 2 * pad, 4))
    ix, iy = int(np.floor(tx)), int(np.floor(ty))
    fx, fy = tx - ix, ty - iy
    # A unit square at x + t overlaps the output squares at x + ix (1 - fx) and x + ix + 1 (fx).
    for dy, wy in ((iy, 1 - fy), (iy + 1, fy)):
        for dx, wx in ((ix, 1 - fx), (ix + 1, fx)):
            y0, x0 = pad + dy, pad + dx
            out[y0 : y0 + h, x0 : x0 + w] += wx * wy * premult
    a = out[..., 3:4]
    straight = np.where(a > 0, out[..., :3] / np.where(a > 0, a, 1), 0)
    a8 = np.floor(a * 255 + 0.5)
    rgb8 = np.where(a8 > 0, np.floor(np.clip(straight, 0, 1) * 255 + 0.5), 0)
    return np.concatenate([rgb8, a8], axis=2).astype(np.uint8)


def within_one_level(a, b):
    """Per channel within 1; where either alpha rounds to 0 only alpha is compared."""
    a, b = a.astype(int), b.astype(int)
    transparent = (a[..., 3] == 0) | (b[..., 3] == 0)
    diff = np.abs(a - b)
    diff[transparent, :3] = 0
    return diff.max() <= 1, diff.max()


# ---------------------------------------------------------------- exactness


def test_identity_reproduces_rgba_exactly():
    image = random_rgba(np.random.default_rng(1), 37, 53)
    out = inkwarp.warp_image(image, np.zeros((37, 53, 2), np.float32))
    np.testing.assert_array_equal(out, image)


def test_identity_makes_rgb_opaque():
    rgb = np.random.default_rng(2).integers(0, 256, (9, 11, 3), dtype=np.uint8)
    out = inkwarp.warp_image(rgb, np.zeros((9, 11, 2)))
    np.testing.assert_array_equal(out[..., :3], rgb)
    assert (out[..., 3] == 255).all()


@settings(max_examples=60, deadline=None)
@given(
    image=arrays(np.uint8, st.tuples(st.integers(1, 12), st.integers(1, 12), st.just(4))),
    matte_seed=st.integers(0, 2**32 - 1),
)
def test_identity_is_exact_for_any_image_and_matte(image, matte_seed):
    image = canonical(image)
    matte = np.random.default_rng(matte_seed).random(image.shape[:2]) < 0.8
    out = inkwarp.warp_image(image, np.zeros(image.shape[:2] + (2,), np.float32), matte)
    np.testing.assert_array_equal(out, image)


@pytest.mark.parametrize("tx,ty", [(3, 0), (-2, 5), (7, -4), (0, 0)])
def test_integer_translation_shifts_exactly(tx, ty):
    h, w = 20, 30
    image = random_rgba(np.random.default_rng(3), h, w)
    out = inkwarp.warp_image(image, constant_field(h, w, tx, ty))
    expected = np.zeros_like(image)
    src = image[max(0, -ty) : h - max(0, ty), max(0, -tx) : w - max(0, tx)]
    expected[max(0, ty) : max(0, ty) + src.shape[0], max(0, tx) : max(0, tx) + src.shape[1]] = src
    np.testing.assert_array_equal(out, expected)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    tx=st.floats(-1.5, 1.5),
    ty=st.floats(-1.5, 1.5),
    size=st.tuples(st.integers(1, 16), st.integers(1, 16)),
)
def test_subpixel_translation_is_the_area_weighted_image(seed, tx, ty, size):
    h, w = size
    pad = 3
    image = random_rgba(np.random.default_rng(seed), h, w)
    # Draw on a larger canvas by padding the image with transparent pixels.
    padded = np.zeros((h + 2 * pad, w + 2 * pad, 4), np.uint8)
    padded[pad : pad + h, pad : pad + w] = image
    out = inkwarp.warp_image(padded, constant_field(h + 2 * pad, w + 2 * pad, tx, ty))
    ok, worst = within_one_level(out, box_translate(image, tx, ty, pad))
    assert ok, f"largest difference {worst} levels"


# ---------------------------------------------------------------- geometry


def test_rotation_leaves_no_crack_inside_the_picture():
    h = w = 64
    image = random_rgba(np.random.default_rng(4), h, w, holes=False)
    angle = 0.5
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    c, s = np.cos(angle), np.sin(angle)
    u, v = x - 31.5, y - 31.5
    field = np.stack([0.6 * (c * u - s * v) - u, 0.6 * (s * u + c * v) - v], axis=-1)
    out = inkwarp.warp_image(image, field.astype(np.float32))
    # Output centres whose preimage (under the scaled rotation) is ≥ 1.5 px inside.
    oy, ox = np.mgrid[0:h, 0:w].astype(np.float64)
    pu, pv = (ox - 31.5) / 0.6, (oy - 31.5) / 0.6
    rx, ry = c * pu + s * pv + 31.5, -s * pu + c * pv + 31.5
    inside = (rx > 1.0) & (rx < w - 2.0) & (ry > 1.0) & (ry < h - 2.0)
    assert inside.sum() > 500
    assert (out[inside, 3] == 255).all()


def test_a_hole_in_the_matte_opens_where_the_field_pulls_it_apart():
    h, w = 24, 32
    image = np.full((h, w, 4), (40, 160, 90, 255), np.uint8)
    matte = np.ones((h, w), bool)
    matte[8:16, 15:17] = False  # a slit, two pixels wide
    image[8:16, 15:17] = 0  # transparent there
    field = np.zeros((h, w, 2), np.float32)
    field[:, :16, 0] = -3.0  # left of the slit moves left
    field[:, 16:, 0] = 3.0  # right of it moves right
    torn = inkwarp.warp_image(image, field, matte)
    # Along the slit's rows the gap is now 2 + 6 px wide: columns 12..19 are clear.
    assert (torn[9:15, 12:20, 3] == 0).all()
    # Without the slit in the matte the same field stretches the middle instead.
    whole = inkwarp.warp_image(np.full((h, w, 4), (40, 160, 90, 255), np.uint8), field)
    assert (whole[:, 3 : w - 3, 3] == 255).all()


def test_cuts_tear_the_picture_where_the_field_pulls_their_sides_apart():
    # A red top and a blue bottom, a horizontal cut between them, the sides pulled apart.
    h, w = 80, 100
    image = np.zeros((h, w, 4), np.uint8)
    image[..., 3] = 255
    image[:40, :, 0] = 255
    image[40:, :, 2] = 255
    points = [[50, 20], [50, 60], [0, 0], [99, 0], [0, 79], [99, 79]]
    moves = [[0, -10], [0, 10], [0, 0], [0, 0], [0, 0], [0, 0]]
    cuts = [[[20, 39.5], [80, 39.5]]]
    field = inkwarp.thin_plate(points, moves, (h, w), cuts=cuts)
    torn = inkwarp.warp_image(image, field, cuts=cuts)
    # A gap opens along the cut's middle: clear pixels between red above and blue below.
    column = torn[30:50, 50]
    clear = np.flatnonzero(column[:, 3] == 0)
    assert len(clear) >= 5
    assert (column[: clear[0] - 1, :3] == (255, 0, 0)).all() and (column[clear[-1] + 2 :, :3] == (0, 0, 255)).all()
    # Past the cut's ends the picture holds together, and without the cuts nothing tears.
    assert (torn[30:50, 2:10, 3] == 255).all() and (torn[30:50, -10:-2, 3] == 255).all()
    assert (inkwarp.warp_image(image, field)[30:50, 2:-2, 3] == 255).all()
    # The cuts are checked as thin_plate checks them.
    with pytest.raises(ValueError, match=r"wrap a single cut in a list"):
        inkwarp.warp_image(image, field, cuts=np.array(cuts[0]))
    with pytest.raises(ValueError, match=r"cuts\[0\] has a value that is not a finite number"):
        inkwarp.warp_image(image, field, cuts=[[[0, 0], [np.nan, 1]]])


def test_the_default_matte_is_the_alpha():
    image = np.full((6, 10, 4), 200, np.uint8)
    image[:, 5, 3] = 0  # a transparent column separates two pieces
    field = np.zeros((6, 10, 2), np.float32)
    field[:, 6:, 0] = 2.0
    out = inkwarp.warp_image(image, field)
    assert (out[:, 5:8, 3] == 0).all()  # the gap widened from 1 to 3 columns
    linked = inkwarp.warp_image(image, field, np.ones((6, 10)))
    assert (linked[:, 6:8, 3] > 0).all()  # connected through the transparent column


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "image,field,matte,message",
    [
        (np.zeros((4, 4, 4), np.float32), np.zeros((4, 4, 2)), None, r"uint8 .* a float image in \[0, 1\] with \(np.clip\(image, 0, 1\) \* 255\)"),
        # A float image a little past 1 (after a filter) is still one in [0, 1].
        (np.full((4, 4, 4), 1.02), np.zeros((4, 4, 2)), None, r"a float image in \[0, 1\]"),
        # Levels 0-255 already (a nested list of ints, a float array of levels): rounded and cast.
        (np.zeros((4, 4, 4), int).tolist(), np.zeros((4, 4, 2)), None, r"dtype int64; convert levels 0-255 with np.clip\(np.round\(image\), 0, 255\)"),
        (np.full((4, 4, 4), 200.0), np.zeros((4, 4, 2)), None, r"dtype float64; convert levels 0-255 with"),
        (np.full((4, 4, 4), 40000, np.uint16), np.zeros((4, 4, 2)), None, r"dtype uint16; convert levels up to 40000 \(16-bit ones: 65535\) with \(image // 257\)"),
        (np.zeros((4, 4, 2), np.uint8), np.zeros((4, 4, 2)), None, r"\(H, W\), \(H, W, 3\) or \(H, W, 4\) \(grey, RGB or RGBA\), got \(4, 4, 2\); make grey and alpha RGBA with np.dstack\(\[image\[..., 0\]\] \* 3 \+ \[image\[..., 1\]\]\)"),
        (np.zeros((4, 4, 1), np.uint8), np.zeros((4, 4, 2)), None, r"got \(4, 4, 1\); pass a grey image as \(H, W\): image\[..., 0\]"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 5, 2)), None, r"\(4, 4, 2\)"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4)), None, r"\(4, 4, 2\)"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 2), complex), None, "real numeric"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 2)), np.ones((3, 4)), r"\(4, 4\)"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 2)), np.array([["a"] * 4] * 4), "matte"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 2)), np.full((4, 4), np.nan), "finite"),
        # As thin_plate's mask says them (it read "matte must have shape (H, W) = (4, 4) ..., got ()").
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 2)), "a.png", r"matte must be an \(H, W\) array, got the path 'a.png'; read the picture first"),
        (np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 2)), np.ones((4, 4, 4)), r"a picture's alpha is matte\[\.\.\., 3\]"),
        (None, None, None, r"image must be an \(H, W\), \(H, W, 3\) or \(H, W, 4\) uint8 array \(grey, RGB or RGBA\), got None"),
        ("cat.png", None, None, r"got the path 'cat.png'; read the picture first, with inkwarp.imaging.read_image"),
        (b"\x89PNG" + bytes(1000), None, None, r"got 1004 bytes of a file; decode them first, with inkwarp.imaging.read_image\(io.BytesIO\(data\)\)"),
    ],
)
def test_bad_arguments_raise_value_error(image, field, matte, message):
    with pytest.raises(ValueError, match=message):
        inkwarp.warp_image(image, field, matte)


def test_a_grey_image_is_warped_as_opaque_rgb():
    # As image_data_uri takes it and a scene reads a grey PNG.
    grey = np.random.default_rng(3).integers(0, 256, (6, 9), dtype=np.uint8)
    field = np.zeros((6, 9, 2), np.float32)
    field[..., 0] = 0.5
    np.testing.assert_array_equal(inkwarp.warp_image(grey, field), inkwarp.warp_image(np.dstack([grey] * 3), field))


@pytest.mark.parametrize("height, width, message", [
    (9000, 9000, "image is 9000×9000 pixels, more than the 64 megapixels inkwarp handles; use a smaller picture"),
    (1, 40000, "image is 40000×1 pixels; each side may be at most 32768; use a smaller picture")])
def test_an_image_past_the_limits_is_refused_as_scenes_refuse_it(height, width, message):
    # Refused from the shape, before a pixel is converted or warped (broadcast arrays: no memory).
    image = np.broadcast_to(np.zeros(1, np.uint8), (height, width, 3))
    with pytest.raises(ValueError, match=message):
        inkwarp.warp_image(image, np.broadcast_to(np.zeros(1, np.float32), (height, width, 2)))


def test_non_finite_field_names_the_first_bad_pixel():
    field = np.zeros((5, 6, 2), np.float32)
    field[3, 4, 1] = np.inf
    field[4, 0, 0] = np.nan
    with pytest.raises(ValueError, match="row 3, column 4"):
        inkwarp.warp_image(np.zeros((5, 6, 3), np.uint8), field)


def test_accepts_non_contiguous_and_float64_input():
    image = np.random.default_rng(5).integers(0, 256, (10, 8, 4), dtype=np.uint8)
    image[..., 3] = 255
    transposed = np.ascontiguousarray(image.transpose(1, 0, 2)).transpose(1, 0, 2)
    assert not transposed.flags.c_contiguous
    out = inkwarp.warp_image(transposed, np.zeros((10, 8, 2), np.float64))
    np.testing.assert_array_equal(out, image)


# ---------------------------------------------------------------- docs


def test_the_documented_examples_run():
    import doctest
    from pathlib import Path

    import inkwarp.imaging

    result = doctest.testmod(inkwarp.imaging)
    assert result.attempted > 0 and result.failed == 0
    page = Path(__file__).resolve().parents[1] / "docs" / "concepts" / "forward-mapping.md"
    result = doctest.testfile(str(page), module_relative=False)
    assert result.attempted > 0 and result.failed == 0


def test_the_pages_figures_exist():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    page = (root / "docs" / "concepts" / "forward-mapping.md").read_text()
    for name in ("mesh", "warps", "edges"):
        assert f"figures/forward-mapping-{name}.png" in page
        assert (root / "docs" / "concepts" / "figures" / f"forward-mapping-{name}.png").is_file()
