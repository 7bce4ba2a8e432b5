"""PNG reading and writing, and a real file round trip through the renderer."""

import os

import numpy as np
import pytest
from PIL import Image

import inkwarp
from inkwarp.imaging import read_image, write_png


def test_png_round_trip_keeps_every_byte(tmp_path):
    rng = np.random.default_rng(7)
    image = rng.integers(0, 256, (33, 47, 4), dtype=np.uint8)
    path = tmp_path / "noise.png"
    write_png(path, image)
    np.testing.assert_array_equal(read_image(path), image)
    # A real PNG that another reader agrees with.
    with Image.open(path) as im:
        assert im.format == "PNG" and im.mode == "RGBA" and im.size == (47, 33)


def test_warp_of_a_png_written_and_read_back(tmp_path):
    # Draw a picture with Pillow, save it as PNG, warp it through the file, read the result.
    picture = Image.new("RGBA", (40, 30), (0, 0, 0, 0))
    picture.paste((220, 40, 40, 255), (5, 5, 20, 25))
    picture.paste((40, 40, 220, 255), (20, 5, 35, 25))
    source = tmp_path / "source.png"
    picture.save(source)

    image = read_image(source)
    field = np.zeros((30, 40, 2), np.float32)
    field[..., 0] = 2.0
    field[..., 1] = -1.0
    out_path = tmp_path / "warped.png"
    write_png(out_path, inkwarp.warp_image(image, field))
    warped = read_image(out_path)

    expected = np.zeros_like(image)
    expected[4:24, 7:37] = image[5:25, 5:35]
    np.testing.assert_array_equal(warped, expected)


def test_read_image_converts_grey_palette_and_rgb(tmp_path):
    grey = tmp_path / "grey.png"
    Image.fromarray(np.arange(12, dtype=np.uint8).reshape(3, 4)).save(grey)
    rgba = read_image(grey)
    assert rgba.shape == (3, 4, 4) and rgba.dtype == np.uint8
    np.testing.assert_array_equal(rgba[..., 0], np.arange(12).reshape(3, 4))
    assert (rgba[..., 3] == 255).all()

    jpeg = tmp_path / "photo.jpg"
    Image.new("RGB", (5, 4), (120, 130, 140)).save(jpeg, quality=95)
    photo = read_image(jpeg)
    assert photo.shape == (4, 5, 4) and (photo[..., 3] == 255).all()


def test_16_bit_grey_reads_as_the_engine_reads_it(tmp_path):
    # Pillow's convert("RGBA") clipped 16-bit grey to white. The engine rounds 16 bits to
    # eight, (v + 128) // 257, but never a faint nonzero level (1, 200) to 0.
    levels = np.array([[0, 1, 200, 32896, 40000, 65535]], np.uint16)
    expected = [0, 1, 1, 128, 156, 255]
    path = tmp_path / "grey16.png"
    Image.fromarray(levels).save(path)
    with Image.open(path) as im:
        assert im.mode == "I;16"
    engine = inkwarp.Scene.from_dict({"inkwarp": 1, "layers": [{"name": "l", "image": "grey16.png"}]},
                                     base_dir=tmp_path).render()
    assert engine[0, :, 0].tolist() == expected
    np.testing.assert_array_equal(read_image(path), engine)
    np.testing.assert_array_equal(inkwarp.Scene.new(path).render(), engine)
    # The other modes Pillow holds wide grey in (older Pillow reads a 16-bit PNG as "I").
    from inkwarp.imaging import rgba_pixels

    for mode in ("I", "I;16B"):
        wide = Image.fromarray(levels).convert(mode) if mode == "I" else Image.frombytes(
            mode, (6, 1), levels.astype(">u2").tobytes())
        np.testing.assert_array_equal(rgba_pixels(wide), engine, err_msg=mode)


def test_read_image_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_image(tmp_path / "missing.png")
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    with pytest.raises(ValueError, match="not an image"):
        read_image(text)


def test_write_png_replaces_atomically_and_leaves_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "frame.png"
    write_png(path, np.zeros((4, 4, 3), np.uint8))
    before = path.read_bytes()

    def broken_save(self, fp, *args, **kwargs):
        fp.write(b"\x89PNG half")
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    with pytest.raises(OSError, match="disk full"):
        write_png(path, np.full((4, 4, 3), 255, np.uint8))
    assert path.read_bytes() == before, "a failed write must leave the old file untouched"
    assert sorted(os.listdir(tmp_path)) == ["frame.png"], "no temporary file may remain"


def test_write_png_rejects_bad_images_before_touching_the_disk(tmp_path):
    path = tmp_path / "bad.png"
    with pytest.raises(ValueError, match="uint8"):
        write_png(path, np.zeros((4, 4, 4), np.float64))
    with pytest.raises(ValueError, match=r"\(H, W, 3\) or \(H, W, 4\)"):
        write_png(path, np.zeros((4, 4), np.uint8))
    assert os.listdir(tmp_path) == []


def test_written_png_has_ordinary_permissions(tmp_path):
    path = tmp_path / "mode.png"
    umask = os.umask(0o022)
    os.umask(umask)
    write_png(path, np.zeros((2, 2, 4), np.uint8))
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
