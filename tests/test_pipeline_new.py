"""`inkwarp new` and `inkwarp.Scene.new`: scenes started from pictures, layered PSDs (written
here with psd-tools) and SVG drawings traced over them."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from PIL import Image

import inkwarp
from inkwarp.cli import main
from inkwarp.svg import TOLERANCE_PX, read_drawing

W, H = 64, 48


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def files(folder):
    return sorted(p.name for p in folder.iterdir())


def write_psd(path, *, mode="RGB"):
    """Three layers: an opaque backdrop, a half-transparent square placed at (30, 20) and
    smaller than the canvas, and a hidden layer."""
    from psd_tools import PSDImage
    from psd_tools.api.layers import PixelLayer

    psd = PSDImage.new(mode, (W, H))
    back = np.zeros((H, W, 4), np.uint8)
    back[..., :3] = np.linspace(20, 220, W, dtype=np.uint8)[None, :, None]
    back[..., 3] = 255
    square = np.zeros((10, 12, 4), np.uint8)
    square[...] = (250, 200, 10, 255)
    square[2:6, 3:9, 3] = 128
    hidden = np.full((8, 8, 4), 255, np.uint8)
    psd.append(PixelLayer.frompil(Image.fromarray(back, "RGBA"), psd, "backdrop", 0, 0))
    psd.append(PixelLayer.frompil(Image.fromarray(square, "RGBA"), psd, "square", 20, 30))
    layer = PixelLayer.frompil(Image.fromarray(hidden, "RGBA"), psd, "ghost", 4, 4)
    layer.visible = False
    psd.append(layer)
    psd.save(path)
    return path


def psd_composite(path):
    from psd_tools import PSDImage

    return np.asarray(PSDImage.open(path).composite().convert("RGBA")).astype(int)


def test_a_psd_becomes_one_layer_per_pixel_layer_and_frame_0_is_its_composite(capsys, tmp_path):
    psd = write_psd(tmp_path / "character.psd")
    code, out, err = run(capsys, "new", psd, "-o", tmp_path / "character.json")
    assert code == 0, err
    assert files(tmp_path) == ["character-backdrop.png", "character-ghost.png",
                               "character-square.png", "character.json", "character.psd"]
    doc = json.loads((tmp_path / "character.json").read_text())
    assert [layer["name"] for layer in doc["layers"]] == ["backdrop", "square", "ghost"]
    assert [layer.get("visible", True) for layer in doc["layers"]] == [True, True, False]
    assert (doc["width"], doc["height"]) == (W, H)
    # The square sits where the PSD puts it, on a canvas-sized image.
    square = np.asarray(Image.open(tmp_path / "character-square.png"))
    assert square.shape == (H, W, 4)
    assert (square[20:30, 30:42, 3] > 0).all() and square[..., 3].sum() == square[20:30, 30:42, 3].sum()
    frame = inkwarp.Scene.load(tmp_path / "character.json").render(frame=0).astype(int)
    assert np.abs(frame - psd_composite(psd)).max() <= 2


def test_embed_puts_the_images_into_the_scene(capsys, tmp_path):
    psd = write_psd(tmp_path / "character.psd")
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "c.json", "--embed", "-q")
    assert code == 0, err
    assert files(tmp_path) == ["c.json", "character.psd"]
    doc = json.loads((tmp_path / "c.json").read_text())
    assert all(layer["image"].startswith("data:image/png;base64,") for layer in doc["layers"])
    frame = inkwarp.Scene.load(tmp_path / "c.json").render().astype(int)
    assert np.abs(frame - psd_composite(psd)).max() <= 2


def test_a_flat_picture_is_one_layer_used_where_it_is(capsys, tmp_path):
    art = np.zeros((H, W, 3), np.uint8)
    art[10:30, 10:40] = (200, 30, 60)
    Image.fromarray(art).save(tmp_path / "photo.png")
    (tmp_path / "scenes").mkdir()
    code, _, err = run(capsys, "new", tmp_path / "photo.png", "-o", tmp_path / "scenes" / "p.json")
    assert code == 0, err
    assert files(tmp_path / "scenes") == ["p.json"]
    doc = json.loads((tmp_path / "scenes" / "p.json").read_text())
    assert doc["layers"] == [{"name": "photo", "image": "../photo.png", "border": "hold"}]
    frame = inkwarp.Scene.load(tmp_path / "scenes" / "p.json").render()
    assert (frame[..., :3] == art).all() and (frame[..., 3] == 255).all()
    # WebP, which scenes do not read, is converted to a PNG beside the scene.
    Image.fromarray(art).save(tmp_path / "photo.webp", lossless=True)
    scene = inkwarp.Scene.new(tmp_path / "photo.webp")
    assert (scene.render()[..., :3] == art).all()


def test_a_phone_photograph_is_read_upright_everywhere(capsys, tmp_path):
    # A portrait photograph as a phone stores it: sideways, tagged "rotate 90° clockwise to
    # view" (EXIF orientation 6). Viewers, browsers and drawing programs show it upright, so
    # a drawing traced over it only lines up if the scene reads it upright too; the engine
    # (scenes, the editor) and Python's readers (inkwarp new, read_image) read it alike.
    from inkwarp.imaging import read_image

    stored = np.zeros((H, W, 3), np.uint8)
    stored[:, : W // 2] = (230, 20, 20)  # red on the stored picture's left half
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(stored).save(tmp_path / "phone.jpg", exif=exif.tobytes(), quality=95)
    upright = read_image(tmp_path / "phone.jpg")
    assert upright.shape == (W, H, 4) and upright[2, H // 2, 0] > 200 and upright[-3, H // 2, 0] < 60  # red on top
    code, out, err = run(capsys, "new", tmp_path / "phone.jpg", "-o", tmp_path / "phone.json")
    assert code == 0, err
    code, out, err = run(capsys, "validate", tmp_path / "phone.json")
    assert code == 0 and f"{H}x{W}" in out, out + err
    frame = inkwarp.Scene.load(tmp_path / "phone.json").render()
    # The engine's JPEG decoder and Pillow's differ by a level or two.
    assert frame.shape == (W, H, 4) and np.abs(frame.astype(int) - upright).max() <= 3
    # A PNG's eXIf chunk turns it the same way. An orientation written only as XMP is read
    # by neither side (the picture stays as stored), so they still agree.
    Image.fromarray(stored).save(tmp_path / "phone.png", exif=exif.tobytes())
    xmp = (b'<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
           b'<rdf:Description xmlns:tiff="http://ns.adobe.com/tiff/1.0/" tiff:Orientation="6"/></rdf:RDF></x:xmpmeta>')
    Image.fromarray(stored).save(tmp_path / "xmp.jpg", xmp=xmp, quality=95)
    for name, shape in [("phone.png", (W, H)), ("xmp.jpg", (H, W))]:
        picture = read_image(tmp_path / name)
        engine = inkwarp.Scene.from_dict({"inkwarp": 1, "layers": [{"name": "p", "image": name}]}, base_dir=tmp_path).render()
        assert picture.shape[:2] == engine.shape[:2] == shape, name
        assert np.abs(engine.astype(int) - picture).max() <= 3, name


def test_scene_new_warns_about_blend_modes_naming_the_layer(tmp_path):
    from psd_tools import PSDImage
    from psd_tools.constants import BlendMode

    path = write_psd(tmp_path / "blend.psd")
    psd = PSDImage.open(path)
    psd[1].blend_mode = BlendMode.MULTIPLY
    psd.save(path)
    with pytest.warns(inkwarp.InkwarpWarning, match="layer 'square' uses the blend mode Multiply"):
        scene = inkwarp.Scene.new(path, fps=12, duration=1)
    assert scene.layers == ["backdrop", "square", "ghost"] and scene.frame_count == 12
    # A hidden layer's mode is said too (it composites as Normal once shown).
    psd = PSDImage.open(path)
    psd[1].blend_mode, psd[2].blend_mode = BlendMode.NORMAL, BlendMode.SCREEN
    psd.save(path)
    with pytest.warns(inkwarp.InkwarpWarning, match=r"layer 'ghost' \(hidden now\) uses the blend mode Screen"):
        inkwarp.Scene.new(path)


@pytest.mark.parametrize("case", ["cut short", "empty", "not-a-psd", "png-named-psd", "cmyk", "svg-without-paths", "bad-suffix", "too large", "far too large"])
def test_bad_pictures_and_drawings_get_one_clear_error_and_leave_nothing(capsys, tmp_path, case):
    picture = tmp_path / "in.psd"
    args = []
    if case == "cut short":  # a copy that did not finish (psd-tools said "Invalid data section size")
        data = write_psd(picture).read_bytes()
        picture.write_bytes(data[: len(data) // 3])
        expect = f"in.psd: the file is cut short ({len(data) // 3:,} bytes, where its layers need"
    elif case == "empty":  # a save that failed: said so, not "not a PSD file"
        picture.write_bytes(b"")
        expect = "in.psd: the file is empty (0 bytes: a save, copy or download that did not finish?); save or copy it again"
    elif case == "not-a-psd":
        # (psd-tools' own words, "24864 is not a valid ColorMode", meant nothing to a user.)
        picture.write_text("notes, saved under the wrong name\n")
        expect = "in.psd: not a PSD file (it does not start as one does); save it from the painting app"
    elif case == "png-named-psd":
        Image.new("RGBA", (8, 6)).save(picture, format="PNG")
        expect = "in.psd: is a PNG picture under a .psd name; rename it to in.png"
    elif case == "cmyk":
        write_psd(picture, mode="CMYK")
        expect = "CMYK colour mode; inkwarp reads RGB documents: convert it"
    elif case == "svg-without-paths":
        write_psd(picture)
        (tmp_path / "d.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" '
                                        'viewBox="0 0 64 48"><text x="1" y="9">hi</text></svg>')
        args = ["--drawing", tmp_path / "d.svg"]
        expect = "d.svg: the SVG has no paths, lines, polylines, polygons"
    elif case == "too large":
        # 72 megapixels (1 bit each, so the file is small): refused naming the picture, not
        # the scene that was never written; Pillow's warnings stay out of it.
        picture = tmp_path / "big.png"
        Image.new("1", (9000, 8000)).save(picture)
        expect = "big.png: the picture is 9000×8000 pixels, more than the 64 megapixels inkwarp handles; scale it down"
    elif case == "far too large":
        picture = tmp_path / "bigger.png"  # past twice Pillow's limit, which it refuses to open
        Image.new("1", (14000, 13000)).save(picture)
        expect = "bigger.png: the picture has more than the 64 megapixels inkwarp handles; scale it down"
    else:
        picture = tmp_path / "in.tga"
        picture.write_bytes(b"x")
        expect = "cannot start a scene from '.tga' files"
    before = files(tmp_path)
    code, out, err = run(capsys, "new", picture, "-o", tmp_path / "s.json", *args)
    assert code == 2
    named = "d.svg" if case == "svg-without-paths" else picture.name
    assert err.startswith("inkwarp new: error: ") and expect in err and named in err
    assert "Traceback" not in err and err.count("\n") == 1
    assert files(tmp_path) == before


def _tiff_orientation(value_type: int) -> bytes:
    """A big-endian EXIF block whose one entry is Orientation 6, stored as a SHORT (type 3)
    or as a LONG (type 4)."""
    import struct

    value = struct.pack(">HH", 6, 0) if value_type == 3 else struct.pack(">I", 6)
    return (b"MM" + struct.pack(">HI", 42, 8) + struct.pack(">H", 1)
            + struct.pack(">HHI", 0x0112, value_type, 1) + value + struct.pack(">I", 0))


@pytest.mark.parametrize("case", ["webp named .jpg", "jfif", "orientation as a long", "exif after the pixels",
                                  "orientation read"])
def test_a_new_scene_reads_its_picture_by_its_contents_as_the_engine_does(capsys, tmp_path, case):
    # `new` went by the suffix and read pictures with Pillow, the engine by the contents with
    # its own decoder: a WebP saved as .jpg (as browsers do) made a scene the engine could
    # not read, and EXIF orientations the two read differently (an Orientation stored as a
    # LONG, a PNG's eXIf chunk after its pixels) made one of the wrong size, which never
    # validated. A .jfif (a JPEG) was refused by its name.
    import struct
    import zlib

    stored = Image.new("RGB", (24, 32), (90, 140, 200))  # 24 wide, 32 high as stored
    stored.paste((255, 0, 0), (0, 0, 8, 8))  # a red block at the stored top left
    upright = (32, 24)  # (width, height) where orientation 6 is applied
    if case == "webp named .jpg":
        picture, size = tmp_path / "download.jpg", (24, 32)
        stored.save(picture, format="WEBP", lossless=True)
    elif case == "jfif":
        picture, size = tmp_path / "photo.jfif", (24, 32)
        stored.save(picture, format="JPEG", quality=95)
    elif case in ("orientation as a long", "orientation read"):
        picture = tmp_path / "phone.jpg"
        stored.save(tmp_path / "t.jpg", quality=95)
        data, exif = (tmp_path / "t.jpg").read_bytes(), b"Exif\0\0" + _tiff_orientation(4 if case == "orientation as a long" else 3)
        picture.write_bytes(data[:2] + b"\xff\xe1" + struct.pack(">H", len(exif) + 2) + exif + data[2:])
        # The engine (and so `new`) reads an Orientation stored as a SHORT only, as the EXIF
        # standard writes it.
        size = (24, 32) if case == "orientation as a long" else upright
    else:
        picture, size = tmp_path / "late.png", (24, 32)
        stored.save(tmp_path / "t.png")
        data, exif = (tmp_path / "t.png").read_bytes(), _tiff_orientation(3)
        chunk = struct.pack(">I", len(exif)) + b"eXIf" + exif + struct.pack(">I", zlib.crc32(b"eXIf" + exif) & 0xFFFFFFFF)
        end = data.index(b"IEND") - 4
        picture.write_bytes(data[:end] + chunk + data[end:])
    code, _, err = run(capsys, "new", picture, "-o", tmp_path / "s.json")
    assert code == 0, err
    doc = json.loads((tmp_path / "s.json").read_text())
    assert (doc["width"], doc["height"]) == size
    assert inkwarp.validate_scene(tmp_path / "s.json") == []
    frame = inkwarp.Scene.load(tmp_path / "s.json").render(time=0.0)
    assert frame.shape == (size[1], size[0], 4)
    # The stored top-left red block, where the orientation put it.
    red = (3, size[0] - 4) if size == upright else (3, 3)
    assert np.abs(frame[red][:3].astype(int) - (255, 0, 0)).max() < 40, frame[red]
    assert (inkwarp.imaging.read_image(picture).shape[:2] == (size[1], size[0])) or case == "webp named .jpg"


def test_a_picture_of_another_format_under_a_png_or_jpeg_name_is_refused_by_its_format(capsys, tmp_path):
    Image.new("RGB", (8, 8)).save(tmp_path / "anim.png", format="GIF")
    code, _, err = run(capsys, "new", tmp_path / "anim.png", "-o", tmp_path / "s.json")
    assert code == 2 and "anim.png: a GIF picture under a .png name; inkwarp reads PNG, JPEG and WebP" in err, err
    assert not (tmp_path / "s.json").exists()


def _display_p3_profile() -> bytes:
    """A minimal ICC v2 RGB profile with Display P3's primaries (D50-adapted), gamma 2.2."""
    import struct

    def s15(v):
        return struct.pack(">i", round(v * 65536))

    def xyz(x, y, z):
        return b"XYZ " + b"\0" * 4 + s15(x) + s15(y) + s15(z)

    curve = b"curv" + b"\0" * 4 + struct.pack(">IH", 1, round(2.2 * 256)) + b"\0\0"
    text = b"Display P3\0"
    tags = [(b"desc", b"desc" + b"\0" * 4 + struct.pack(">I", len(text)) + text + b"\0" * 78),
            (b"wtpt", xyz(0.9642, 1.0, 0.8249)), (b"rXYZ", xyz(0.5151, 0.2412, -0.0011)),
            (b"gXYZ", xyz(0.2920, 0.6922, 0.0419)), (b"bXYZ", xyz(0.1571, 0.0666, 0.7841)),
            (b"rTRC", curve), (b"gTRC", curve), (b"bTRC", curve), (b"cprt", b"text\0\0\0\0CC0\0")]
    offset, table, data = 128 + 4 + 12 * len(tags), b"", b""
    for signature, body in tags:
        data += b"\0" * (-(offset + len(data)) % 4)
        table += signature + struct.pack(">II", offset + len(data), len(body))
        data += body
    header = (struct.pack(">I", offset + len(data)) + b"lcms" + struct.pack(">I", 0x02100000) + b"mntrRGB XYZ "
              + b"\0" * 12 + b"acspAPPL" + b"\0" * 24 + s15(0.9642) + s15(1.0) + s15(0.8249) + b"\0" * 48)
    return header + struct.pack(">I", len(tags)) + table + data


def test_a_picture_in_display_p3_renders_as_a_viewer_shows_it(capsys, tmp_path):
    # A phone's JPEG in Display P3 was rendered as if its numbers were sRGB: a red a viewer
    # shows as (252, 0, 0) came out (230, 30, 30), every colour duller. The engine reads no
    # profile, so `new` converts such a picture to sRGB into a PNG beside the scene.
    from PIL import ImageCms

    icc = _display_p3_profile()
    pixels = np.zeros((16, 48, 3), np.uint8)
    pixels[:, :16], pixels[:, 16:32], pixels[:, 32:] = (230, 30, 30), (40, 200, 60), (225, 160, 120)
    Image.fromarray(pixels).save(tmp_path / "phone.png", icc_profile=icc)
    shown = np.asarray(ImageCms.profileToProfile(Image.open(tmp_path / "phone.png"), ImageCms.ImageCmsProfile(
        __import__("io").BytesIO(icc)), ImageCms.createProfile("sRGB"), outputMode="RGB"))
    assert np.abs(shown[0, 8].astype(int) - (230, 30, 30)).max() > 15  # a real difference to make
    code, out, err = run(capsys, "new", tmp_path / "phone.png", "-o", tmp_path / "s.json")
    assert code == 0 and "converted from its colour profile (Display P3) to sRGB" in err, err
    frame = inkwarp.Scene.load(tmp_path / "s.json").render(time=0.0)
    assert np.abs(frame[..., :3].astype(int) - shown).max() <= 1
    # A picture in sRGB stays as it is, where it is.
    Image.fromarray(pixels).save(tmp_path / "plain.png", icc_profile=ImageCms.ImageCmsProfile(
        ImageCms.createProfile("sRGB")).tobytes())
    code, _, err = run(capsys, "new", tmp_path / "plain.png", "-o", tmp_path / "p.json")
    assert code == 0 and "colour profile" not in err
    assert json.loads((tmp_path / "p.json").read_text())["layers"][0]["image"] == "plain.png"


# --- SVG drawings ----------------------------------------------------------------------------

SVG = """<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
     width="128" height="96" viewBox="0 0 128 96">
  <g transform="translate(0.5 0.5)">
    <path id="brow" d="M 20 20 C 30 6, 50 6, 60 20 S 90 34, 100 20" fill="none"/>
    <path id="jaw" d="M10,60 L40,80 l30,0" style="fill:none;stroke:black"/>
    <polyline id="arm" points="70,40 90,50 110,40" fill="none"/>
    <polygon id="plate" points="10,10 30,10 30,30" fill="red"/>
    <line id="shoulder-cut" x1="40" y1="40" x2="60" y2="44"/>
    <path class="knife cut" d="M 70 70 Q 90 90 110 70" fill="none"/>
    <circle id="eye" cx="80" cy="12" r="2"/>
    <circle id="head" cx="100" cy="70" r="12" fill="#fc0"/>
    <ellipse id="ring" cx="30" cy="45" rx="8" ry="5" fill="none" transform="rotate(30 30 45)"/>
    <path id="nose" d="M 64 40"/>
  </g>
</svg>
"""


def dense_bezier(p0, c1, c2, p3, n=400):
    t = np.linspace(0, 1, n)[:, None]
    return ((1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * c1 + 3 * (1 - t) * t * t * c2
            + t ** 3 * p3)


def distance_to(points, curve):
    d = np.sqrt(((points[:, None, :] - curve[None]) ** 2).sum(2))
    return d.min(1)


def test_a_closed_shape_named_cut_tears_all_around(tmp_path):
    # A rectangle whose id says cut lost its fourth (closing) side: a cut of three sides.
    # A cut is an open polyline (DESIGN section 3): it runs back to its start.
    svg = tmp_path / "d.svg"
    svg.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {H}">'
                   '<rect id="cut1" x="10" y="10" width="20" height="30" fill="red"/>'
                   '<path id="slit-cut" d="M 5 5 L 15 5"/></svg>')
    features, _ = read_drawing(svg, W, H)
    by_id = {f["id"]: f for f in features}
    assert by_id["cut1"] == {"id": "cut1", "kind": "cut",
                             "rest": [[9.5, 9.5], [29.5, 9.5], [29.5, 39.5], [9.5, 39.5], [9.5, 9.5]]}, by_id["cut1"]
    assert "closed" not in by_id["slit-cut"]


def test_an_svg_with_every_element_kind_becomes_the_expected_features(tmp_path):
    svg = tmp_path / "drawing.svg"
    svg.write_text(SVG)
    features, notes = read_drawing(svg, W, H)  # the 128x96 viewBox over a 64x48 picture
    by_id = {f["id"]: f for f in features}
    kinds = {f["id"]: f["kind"] for f in features}
    assert kinds == {"brow": "spline", "jaw": "polyline", "arm": "polyline", "plate": "region",
                     "shoulder-cut": "cut", "cut-1": "cut", "eye": "point", "head": "region",
                     "ring": "spline", "nose": "point"}

    def px(x, y):  # SVG user units (with the group's half-unit shift) to scene pixels
        return [(x + 0.5) / 2 - 0.5, (y + 0.5) / 2 - 0.5]

    assert by_id["jaw"]["rest"] == [px(10, 60), px(40, 80), px(70, 80)]
    assert by_id["plate"]["rest"] == [px(10, 10), px(30, 10), px(30, 30)]
    assert by_id["shoulder-cut"]["rest"] == [px(40, 40), px(60, 44)]
    assert by_id["eye"]["rest"] == [px(80, 12)]
    assert by_id["nose"]["rest"] == [px(64, 40)]
    assert by_id["head"]["curve"] == "spline" and by_id["ring"].get("closed") is True
    # The brow's spline (as the engine samples it) stays within 0.25 px of the two Béziers.
    to_px = lambda pts: (np.asarray(pts, float) + 0.5) / 2 - 0.5  # noqa: E731
    truth = np.vstack([dense_bezier(*to_px([[20, 20], [30, 6], [50, 6], [60, 20]])),
                       dense_bezier(*to_px([[60, 20], [70, 34], [90, 34], [100, 20]]))])
    rest = np.asarray(by_id["brow"]["rest"])
    samples, _ = inkwarp.sample("spline", rest, rest, spacing=0.05)
    assert distance_to(samples, truth).max() <= TOLERANCE_PX
    assert distance_to(truth, samples).max() <= TOLERANCE_PX
    # The circle's region outline is a circle of radius 6 px about its centre.
    head = np.asarray(by_id["head"]["rest"])
    outline, _ = inkwarp.sample("spline", head, head, closed=True, spacing=0.05)
    centre = np.array(px(100, 70))
    radius = np.hypot(*(outline - centre).T)
    assert np.abs(radius - 6).max() <= TOLERANCE_PX
    # The quadratic cut is flattened to a polyline within the tolerance.
    cut = np.asarray(by_id["cut-1"]["rest"])
    quad = dense_bezier(*to_px([[70, 70], [70 + 2 / 3 * 20, 70 + 2 / 3 * 20],
                                [110 - 2 / 3 * 20, 70 + 2 / 3 * 20], [110, 70]]))
    assert distance_to(quad, np.vstack([np.linspace(a, b, 50) for a, b in zip(cut, cut[1:])])
                       ).max() <= TOLERANCE_PX
    # The rotated ellipse: its points lie on the ellipse rotated by 30 degrees.
    ring = np.asarray(by_id["ring"]["rest"]) - np.array(px(30, 45))
    angle = np.radians(-30)
    u = ring @ np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
    assert np.allclose((u[:, 0] / 4) ** 2 + (u[:, 1] / 2.5) ** 2, 1, atol=2e-3)
    # The one note names the cuts, which move nothing and tear the picture.
    assert len(notes) == 1 and "'shoulder-cut', 'cut-1' are cuts (the word 'cut'" in notes[0], notes


def drawn_kinds(tmp_path, inside):
    """Each feature's kind, and the notes, of a 64 × 48 drawing of the SVG elements `inside`."""
    svg = tmp_path / "drawing.svg"
    svg.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 64 48">{inside}</svg>')
    features, notes = read_drawing(svg, 64, 48)
    return {f["id"]: f["kind"] for f in features}, notes


def test_fills_from_a_style_sheet_and_clear_fills_make_outlines_not_regions(tmp_path):
    # Illustrator's default SVG: fills set by class rules in a <style> sheet. An outline
    # with `fill: none` there moved its inside as a region.
    kinds, notes = drawn_kinds(tmp_path, '<defs><style>'
                   '/* Illustrator */ .cls-1{fill:none;stroke:#231f20;stroke-miterlimit:10}'
                   '.cls-2,.cls-3{fill:#fff} polygon.wire{fill:none} #lid{fill:red !important}'
                   'g .deep{fill:none}</style></defs>'
                   '<circle id="head" class="cls-1" cx="32" cy="20" r="10"/>'
                   '<polygon id="body" class="cls-3 x" points="20,30 44,30 44,46"/>'
                   '<polygon id="wire" class="wire" points="2,2 10,2 10,10"/>'
                   '<polygon id="lid" class="cls-1" points="2,20 10,20 10,28"/>'
                   '<polygon id="inline" class="cls-1" style="fill:#0f0" points="2,30 10,30 10,38"/>'
                   '<rect id="clear" x="50" y="2" width="8" height="8" fill="transparent"/>'
                   '<rect id="faded" x="50" y="12" width="8" height="8" fill="red" fill-opacity="0"/>'
                   '<rect id="rgba" x="50" y="22" width="8" height="8" fill="rgba(0, 0, 0, 0)"/>'
                   '<rect id="deep" class="deep" x="50" y="32" width="8" height="8"/>')
    assert kinds == {"head": "spline", "body": "region", "wire": "polyline", "lid": "region",
                     "inline": "region", "clear": "polyline", "faded": "polyline",
                     "rgba": "polyline", "deep": "region"}, kinds
    assert len(notes) == 1 and "the style rule 'g .deep' is not applied" in notes[0], notes


@pytest.mark.parametrize("name, cut", [("neck-cut", True), ("cut2", True), ("neckCut", True),
                                       ("Cuts", True), ("neck_x5F_cut", True), ("cute-smile", False),
                                       ("haircut-line", False), ("shortcut", False), ("executeGroup", None)])
def test_a_cut_is_named_by_the_word_cut_not_by_those_letters(tmp_path, name, cut):
    # An id such as "cute-smile" made a cut that tore the picture and moved nothing.
    kinds, notes = drawn_kinds(tmp_path, f'<path id="{name}" d="M 10 10 Q 20 20 30 10" fill="none"/>')
    assert (kinds[name] == "cut") is bool(cut)
    assert any(f"{name!r} is a cut" in n for n in notes) is bool(cut), notes
    # A name with a word that starts or ends with those letters says it is not a cut, and how
    # to name one (not one with them inside a word: "executeGroup").
    assert any(f"{name!r} has the letters 'cut' in a name but is not a cut" in n for n in notes) is (cut is False), notes


def test_a_name_with_the_letters_cut_on_two_elements_is_named_once_in_the_singular(tmp_path):
    # ("'shortcut' have the letters 'cut' in a name but are not a cut": counted before the
    # repeated name was left out.)
    _, notes = drawn_kinds(tmp_path, '<path class="shortcut" d="M 10 10 L 30 10" fill="none"/>'
                                     '<path class="shortcut" d="M 10 20 L 30 20" fill="none"/>')
    assert any("'shortcut' has the letters 'cut' in a name but is not a cut" in n for n in notes), notes


def test_style_sheet_importance_at_rules_and_inherited_fills_are_read_as_css_reads_them(tmp_path):
    kinds, notes = drawn_kinds(tmp_path, '<style>'
                   '@import url(more.css); @charset "utf-8";'
                   '.o{fill:none ! IMPORTANT} .p{fill:none}'
                   '@media print{.q{fill:none}} .r{fill:#fff}</style>'
                   '<polygon id="important" class="o" style="fill:#fff" points="2,2 10,2 10,10"/>'
                   '<polygon id="inline" class="p" style="fill:#fff" points="2,12 10,12 10,20"/>'
                   '<polygon id="print-only" class="q" points="2,22 10,22 10,30"/>'
                   '<polygon id="after-import" class="r" points="2,32 10,32 10,40"/>'
                   '<g fill="none"><polygon id="inherits" fill="inherit" points="20,2 28,2 28,10"/>'
                   '<polygon id="initial" style="fill:initial" points="20,12 28,12 28,20"/></g>')
    # !important beats the style attribute; a rule inside @media print is not the screen's;
    # a rule after an @import still applies; inherit takes the group's none, initial black.
    assert kinds == {"important": "polyline", "inline": "region", "print-only": "region",
                     "after-import": "region", "inherits": "polyline", "initial": "region"}, kinds
    assert len(notes) == 1 and "style rules inside @media or @supports blocks are not applied" in notes[0], notes


def test_text_and_pictures_in_a_drawing_are_named_as_left_out(tmp_path):
    # A label or a reference picture left in the tracing: no feature, and a note says so
    # (it was dropped without a word).
    svg = tmp_path / "drawing.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="64" height="48">'
                   '<path id="brow" d="M 10 10 L 30 12" fill="none"/>'
                   '<text id="label" x="5" y="40">left arm</text>'
                   '<image id="ref" href="ref.png" width="64" height="48"/></svg>')
    features, notes = read_drawing(svg, 64, 48)
    assert [f["id"] for f in features] == ["brow"]
    assert len(notes) == 2 and "<text> id='label' is left out: text makes no feature" in notes[0], notes
    assert "<image> id='ref' is left out: a picture in the drawing makes no feature" in notes[1], notes


def test_hidden_shapes_of_a_drawing_are_left_out_with_a_note(tmp_path):
    # A shape hidden with visibility became a feature without a word, where one hidden with
    # display: none was left out with a note. Visibility inherits, and a shape inside a
    # hidden group may show itself again.
    svg = tmp_path / "drawing.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="64" height="48">'
                   '<style>.off { visibility: collapse }</style>'
                   '<path id="brow" d="M 10 10 L 30 12" fill="none"/>'
                   '<path id="old" visibility="hidden" d="M 10 20 L 30 22" fill="none"/>'
                   '<path id="spare" class="off" d="M 10 25 L 30 27" fill="none"/>'
                   '<g id="sketch" style="visibility:hidden"><path id="inner" d="M 10 30 L 30 32" fill="none"/>'
                   '<path id="lip" visibility="visible" d="M 10 40 L 30 42" fill="none"/></g>'
                   '<g display="none"><path id="gone" d="M 5 5 L 9 9"/></g></svg>')
    features, notes = read_drawing(svg, 64, 48)
    assert [f["id"] for f in features] == ["brow", "lip"]
    assert [n.split(": ", 1)[1] for n in notes] == [
        "<path> id='old' is hidden (visibility: hidden) and left out",
        "<path> id='spare' is hidden (visibility: collapse) and left out",
        "<g> id='sketch' is hidden (visibility: hidden) and left out, with what it holds but shapes set to "
        "visibility: visible",
        "<g> (without id) is hidden (display: none) and left out"], notes
    # A value CSS does not know is ignored; a hidden <svg> hides all, and saying so beats
    # "the SVG has no paths".
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="64" height="48">'
                   '<path id="brow" visibility="bogus" d="M 10 10 L 30 12" fill="none"/></svg>')
    assert [f["id"] for f in read_drawing(svg, 64, 48)[0]] == ["brow"]
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="64" height="48" visibility="hidden">'
                   '<path id="brow" d="M 10 10 L 30 12" fill="none"/></svg>')
    with pytest.raises(inkwarp.InputError, match="every shape of the SVG is hidden"):
        read_drawing(svg, 64, 48)


def test_new_with_a_drawing_makes_a_scene_that_renders(capsys, tmp_path):
    psd = write_psd(tmp_path / "character.psd")
    (tmp_path / "drawing.svg").write_text(SVG)
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "c.json", "--drawing",
                       tmp_path / "drawing.svg")
    assert code == 0, err
    scene = inkwarp.Scene.load(tmp_path / "c.json")
    assert "brow" in scene.features and len(scene.features) == 10
    assert np.abs(scene.render().astype(int) - psd_composite(psd)).max() <= 2


def test_new_says_what_validate_would_note_of_the_scene_it_wrote(capsys, tmp_path):
    # A traced point wholly off the picture (a drawing for a larger picture): new printed
    # only "wrote s.json"; the note came at the first validate.
    Image.fromarray(np.full((H, W, 4), 255, np.uint8)).save(tmp_path / "p.png")
    (tmp_path / "d.svg").write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}">'
                                    '<path id="lip" d="M 4 4 L 20 4" fill="none"/><circle id="far" cx="500" cy="9" r="1"/></svg>')
    out = tmp_path / "s.json"
    code, stdout, err = run(capsys, "new", tmp_path / "p.png", "-o", out, "--drawing", tmp_path / "d.svg")
    assert code == 0 and stdout.startswith(f"wrote {out}"), (stdout, err)
    assert err.splitlines() == [f"inkwarp new: note: {out}: features[1]: 'far' lies wholly off the picture, so it moves "
                                f"nothing: its rest points span x 499.5 to 499.5, y 8.5 to 8.5, the picture's pixel "
                                f"centres x 0 to {W - 1}, y 0 to {H - 1}"], err


def test_bad_path_data_names_the_element(capsys, tmp_path):
    Image.fromarray(np.zeros((H, W, 4), np.uint8)).save(tmp_path / "p.png")
    (tmp_path / "d.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg">'
                                    '<path id="lip" d="M 1 2 C 3 4"/></svg>')
    code, _, err = run(capsys, "new", tmp_path / "p.png", "-o", tmp_path / "s.json",
                       "--drawing", tmp_path / "d.svg")
    assert code == 2 and "d.svg: <path> id='lip'" in err and "C needs 6 numbers" in err
    assert not (tmp_path / "s.json").exists()
    assert not [p for p in os.listdir(tmp_path) if ".part" in p]


def test_a_repeated_id_is_renamed_with_a_note(tmp_path):
    svg = tmp_path / "twice.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="64" height="48">'
                   '<path id="arm" d="M 4 4 L 20 4" fill="none"/>'
                   '<path id="arm" d="M 4 20 L 20 20" fill="none"/></svg>')
    features, notes = read_drawing(svg, 64, 48)
    assert [f["id"] for f in features] == ["arm", "arm-2"]
    assert any("'arm' is taken by an earlier feature; this path is 'arm-2'" in n for n in notes), notes


def test_groups_are_flattened_with_their_opacity_and_a_note(tmp_path):
    from psd_tools import PSDImage
    from psd_tools.api.layers import Group, PixelLayer
    from psd_tools.constants import BlendMode

    psd = PSDImage.new("RGB", (32, 24))
    psd.append(PixelLayer.frompil(Image.new("RGBA", (32, 24), (200, 0, 0, 255)), psd, "back", 0, 0))
    eye = PixelLayer.frompil(Image.new("RGBA", (8, 8), (0, 0, 200, 255)), psd, "eye", 4, 4)
    psd.append(eye)
    group = Group.group_layers(psd, [eye], name="face")
    group.opacity = 128
    psd.save(tmp_path / "g.psd")
    eye.blend_mode = BlendMode.MULTIPLY
    psd.save(tmp_path / "m.psd")
    with pytest.warns(inkwarp.InkwarpWarning, match=r"group 'face' is flattened into its layers \(names kept, its opacity \(50 %\)"):
        scene = inkwarp.Scene.new(tmp_path / "g.psd")
    assert scene.layers == ["back", "eye"]
    # At full opacity no overlap shows differently, and the note says only what it does.
    group.opacity = 255
    eye.blend_mode = BlendMode.NORMAL
    far = PixelLayer.frompil(Image.new("RGBA", (6, 6), (0, 200, 0, 255)), psd, "far", 500, 500)
    psd.append(far)
    psd.save(tmp_path / "full.psd")
    with pytest.warns(inkwarp.InkwarpWarning) as said:
        full = inkwarp.Scene.new(tmp_path / "full.psd")
    notes = [str(w.message) for w in said]
    assert any("group 'face' is flattened into its layers (names kept, its visibility applied to each of them)" in n
               for n in notes) and not any("overlap" in n for n in notes), notes
    # A layer wholly off the canvas comes in empty, and is said to.
    assert "far" in full.layers and any("layer 'far' lies wholly off the 32x24 canvas" in n for n in notes), notes
    # A grouped layer is named as the scene names it, its group beside.
    with pytest.warns(inkwarp.InkwarpWarning) as said:
        inkwarp.Scene.new(tmp_path / "m.psd")
    assert any("layer 'eye' (in group 'face') uses the blend mode Multiply" in str(w.message) for w in said), said
    assert np.abs(scene.render().astype(int) - psd_composite(tmp_path / "g.psd")).max() <= 2


def test_a_layer_clipped_to_the_one_below_is_cut_to_its_shape(tmp_path):
    # Shading clipped to a character's base layer (painting apps' clipping masks) covered
    # the whole canvas, silently.
    from psd_tools import PSDImage
    from psd_tools.api.layers import Group, PixelLayer

    psd = PSDImage.new("RGB", (40, 30))
    psd.append(PixelLayer.frompil(Image.new("RGBA", (40, 30), (255, 255, 255, 255)), psd, "paper", 0, 0))
    body = np.zeros((30, 40, 4), np.uint8)
    body[5:25, 8:32] = (200, 0, 0, 255)
    body[10:20, 14:26, 3] = 128  # a half-transparent part: the shade is half there too
    psd.append(PixelLayer.frompil(Image.fromarray(body, "RGBA"), psd, "body", 0, 0))
    shade = PixelLayer.frompil(Image.new("RGBA", (40, 15), (0, 0, 200, 255)), psd, "shade", 15, 0)
    psd.append(shade)
    shade.clipping = True
    hidden = PixelLayer.frompil(Image.new("RGBA", (10, 10), (0, 200, 0, 255)), psd, "hidden", 0, 0)
    psd.append(hidden)
    hidden.visible = False
    glint = PixelLayer.frompil(Image.new("RGBA", (40, 30), (250, 250, 0, 255)), psd, "glint", 0, 0)
    psd.append(glint)
    glint.clipping = True  # clipped to the hidden layer below it: hidden with it
    psd.save(tmp_path / "c.psd")
    with pytest.warns(inkwarp.InkwarpWarning) as said:
        scene = inkwarp.Scene.new(tmp_path / "c.psd")
    notes = [str(w.message) for w in said]
    assert any("layer 'shade' is clipped to 'body'" in n for n in notes), notes
    assert scene.layers == ["paper", "body", "shade", "hidden", "glint"]
    picture = inkwarp.importing.read_picture(tmp_path / "c.psd")
    alpha = {layer.name: layer.image[..., 3].astype(int) for layer in picture.layers}
    assert (alpha["shade"][:15] == 0).all() and (alpha["shade"][15:, :8] == 0).all()
    assert (alpha["shade"][15:25, 8:14] == 255).all() and abs(alpha["shade"][17, 20] - 128) <= 1
    assert [layer.visible for layer in picture.layers] == [True, True, True, False, False]
    # As the PSD shows it, but where the body is half there: two layers "over" one another
    # mix the shade with the body's colour there, where the clipping group shows the shade.
    solid = (alpha["body"] == 0) | (alpha["body"] == 255)
    assert np.abs(scene.render().astype(int) - psd_composite(tmp_path / "c.psd"))[solid].max() <= 2


def test_a_hidden_layer_of_a_base_group_does_not_shape_what_is_clipped_to_it(tmp_path):
    from psd_tools import PSDImage
    from psd_tools.api.layers import Group, PixelLayer

    from inkwarp.importing import read_picture

    psd = PSDImage.new("RGB", (40, 30))
    psd.append(PixelLayer.frompil(Image.new("RGBA", (40, 30), (255, 255, 255, 255)), psd, "paper", 0, 0))
    small = PixelLayer.frompil(Image.new("RGBA", (10, 10), (200, 0, 0, 255)), psd, "small", 5, 5)
    sketch = PixelLayer.frompil(Image.new("RGBA", (40, 30), (0, 200, 0, 255)), psd, "old sketch", 0, 0)
    psd.append(small)
    psd.append(sketch)
    Group.group_layers(psd, [small, sketch], name="body")
    sketch.visible = False
    shade = PixelLayer.frompil(Image.new("RGBA", (40, 30), (0, 0, 200, 255)), psd, "shade", 0, 0)
    psd.append(shade)
    shade.clipping = True
    psd.save(tmp_path / "h.psd")
    picture = read_picture(tmp_path / "h.psd")
    assert any("layer 'shade' is clipped to 'body'" in note for note in picture.notes), picture.notes
    shade_alpha = next(layer.image[..., 3] for layer in picture.layers if layer.name == "shade")
    assert (shade_alpha > 0).sum() == 100 and (shade_alpha[5:15, 5:15] == 255).all()
    with pytest.warns(inkwarp.InkwarpWarning):
        scene = inkwarp.Scene.new(tmp_path / "h.psd")
    assert np.abs(scene.render().astype(int) - psd_composite(tmp_path / "h.psd")).max() <= 2


def test_layer_names_that_share_a_file_name_or_are_long_each_get_an_image(capsys, tmp_path):
    """Layer names are free text: "a b" and "a-b" share a slug (this once looped forever
    when a third layer's fallback name was taken too), case-insensitive file systems take
    "Arm" for "arm", and a PSD name of 250 characters made a file name too long (exit 1)."""
    from psd_tools import PSDImage
    from psd_tools.api.layers import PixelLayer

    names = ["a-b", "a-b-2", "a b", "arm", "Arm", "x" * 250, "../../up", "Ébauche 1", "Œil", "Straße"]
    psd = PSDImage.new("RGB", (16, 12))
    for i, name in enumerate(names):
        picture = Image.new("RGBA", (16, 12), (0, 0, 0, 0))
        picture.putpixel((i, i), (10 + 20 * i, 0, 0, 255))
        psd.append(PixelLayer.frompil(picture, psd, name, 0, 0))
    psd.save(tmp_path / "n.psd")
    out = tmp_path / "scene"
    out.mkdir()
    code, _, err = run(capsys, "new", tmp_path / "n.psd", "-o", out / "n.json", "--quiet")
    assert code == 0, err
    doc = json.loads((out / "n.json").read_text())
    images = [layer["image"] for layer in doc["layers"]]
    assert len({image.casefold() for image in images}) == len(names)
    assert sorted(images + ["n.json"]) == files(out)  # all inside the scene's folder
    assert all(len(image) <= 80 for image in images)
    # An accented letter keeps its base letter, and a few others are spelled out.
    assert images[-3:] == ["n-Ebauche-1.png", "n-OEil.png", "n-Strasse.png"]
    # A name's next file is numbered by a count of its own, not by the layer's place.
    assert images[:5] == ["n-a-b.png", "n-a-b-2.png", "n-a-b-3.png", "n-arm.png", "n-Arm-2.png"]
    for i, image in enumerate(images):  # each layer's own pixels under its own file
        pixels = np.asarray(Image.open(out / image))
        assert pixels[i, i, 3] == 255 and pixels[i, i, 0] == 10 + 20 * i
        assert pixels[..., 3].sum() == 255


def test_new_refuses_to_replace_an_existing_scene_unless_forced(capsys, tmp_path, monkeypatch):
    psd = write_psd(tmp_path / "character.psd")
    scene = tmp_path / "character.json"
    scene.write_text('{"traced": "a day of work"}')
    code, _, err = run(capsys, "new", psd, "-o", scene)
    assert code == 2 and "character.json" in err and "already exists" in err and "--force" in err
    assert scene.read_text() == '{"traced": "a day of work"}'
    assert files(tmp_path) == ["character.json", "character.psd"]
    code, _, err = run(capsys, "new", psd, "-o", scene, "--force", "-q")
    assert code == 0, err
    assert inkwarp.Scene.load(scene).width == W
    # Again: the scene and its images, named alike (as given), in the plural.
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "new", "character.psd", "-o", "character.json")
    assert code == 2 and "character-square.png" in err and "already exist;" in err and str(tmp_path) not in err, err


def test_a_forced_new_scene_names_the_images_of_the_one_it_replaced_that_it_leaves(capsys, tmp_path):
    # `new --force` over a scene of another picture left that scene's layer images beside
    # the new one without a word.
    psd = write_psd(tmp_path / "character.psd")
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "s.json", "-q")
    assert code == 0, err
    flat = tmp_path / "flat.png"
    Image.new("RGBA", (W, H), (9, 9, 9, 255)).save(flat)
    code, _, err = run(capsys, "new", flat, "-o", tmp_path / "s.json", "--force")
    assert code == 0, err
    assert ("s.json: the scene it replaced used s-backdrop.png, s-ghost.png, s-square.png, which the new one "
            "does not; left in place (delete them if nothing else uses them)") in err, err
    assert files(tmp_path) == ["character.psd", "flat.png", "s-backdrop.png", "s-ghost.png", "s-square.png", "s.json"]
    # Replaced by a scene that writes the same images again: nothing to say.
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "s.json", "--force")
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "s.json", "--force")
    assert code == 0 and "replaced" not in err, err
    # The same picture spelled another way is the new scene's own; a scene that is no scene
    # (what --force is for) is replaced with nothing to say.
    for old in ({"layers": [{"name": "f", "image": "./flat.png"}, {"name": "g", "image": str(flat)}]},
                {"layers": None}, [1, 2], "not json"):
        (tmp_path / "t.json").write_text(old if isinstance(old, str) else json.dumps(old))
        code, _, err = run(capsys, "new", flat, "-o", tmp_path / "t.json", "--force")
        assert code == 0 and "replaced" not in err, (old, err)


def test_a_photoshop_document_under_another_name_is_read_as_one(capsys, tmp_path):
    # The kind is read from the contents (as a WebP named .jpg is converted): it was refused
    # with "inkwarp reads PNG, JPEG and WebP", though inkwarp reads PSD files.
    psd = write_psd(tmp_path / "character.psd")
    named = tmp_path / "character.png"
    named.write_bytes(psd.read_bytes())
    code, _, err = run(capsys, "new", named, "-o", tmp_path / "c.json", "-q")
    assert code == 0, err
    assert inkwarp.Scene.load(tmp_path / "c.json").layers == inkwarp.Scene.new(psd).layers


@pytest.mark.parametrize("option,value,message", [
    ("--fps", "inf", "--fps inf: numbers must be finite, found inf"),
    ("--fps", "0", "--fps 0: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000, found 0.0"),
    ("--fps", "5000", "--fps 5000: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000, found 5000.0"),
    ("--fps", "1e-9", "--fps 1e-09: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000"),
    ("--duration", "inf", "--duration inf: give a length in seconds > 0"),
    ("--duration", "1e9", "--duration 1e+09: the duration may be at most"),
])
def test_new_names_the_option_past_a_scenes_limits(capsys, tmp_path, option, value, message):
    psd = write_psd(tmp_path / "character.psd")
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "c.json", option, value)
    assert code == 2 and message in err, err
    assert files(tmp_path) == ["character.psd"]


def test_new_names_every_option_past_the_limits_at_once(capsys, tmp_path):
    psd = write_psd(tmp_path / "character.psd")
    code, _, err = run(capsys, "new", psd, "-o", tmp_path / "c.json", "--fps", "5000", "--duration", "1e9")
    assert code == 2 and "--fps 5000: frames per second must be a number from 0.001 (one frame every 1000 s) to 1000, found 5000.0" in err, err
    assert "--duration 1e+09: the duration may be at most" in err and "\n  duration" not in err, err


def test_validate_notes_a_picture_whose_colour_profile_is_not_applied(capsys, tmp_path):
    # A scene written by hand that points at a Display P3 picture renders it duller than a
    # viewer shows it, without a word; `inkwarp new` converts such a picture, validate notes it.
    Image.fromarray(np.full((16, 24, 3), (230, 30, 30), np.uint8)).save(tmp_path / "phone.png",
                                                                      icc_profile=_display_p3_profile())
    Image.fromarray(np.full((16, 24, 3), 200, np.uint8)).save(tmp_path / "plain.png")
    doc = {"inkwarp": 1, "fps": 4, "duration": 1, "layers": [{"name": "bg", "image": "plain.png"},
                                                             {"name": "face", "image": "phone.png"}]}
    (tmp_path / "s.json").write_text(json.dumps(doc))
    code, out, _ = run(capsys, "validate", tmp_path / "s.json")
    assert code == 0
    assert out.splitlines()[1:] == [f"note: {tmp_path / 's.json'}: layers[1].image: layer 'face''s picture carries a "
                                    "colour profile (Display P3) that inkwarp does not apply: its numbers render as "
                                    "sRGB, duller than a viewer shows them; convert the picture to sRGB (inkwarp new "
                                    "does so)"]
