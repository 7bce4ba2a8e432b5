"""Outputs for pipelines: transparent video (WebM VP9, ProRes 4444 MOV, APNG), 1-bit GIF,
sprite sheets with TexturePacker JSON, background overrides, and farm chunks that equal a
sequential render. Videos are decoded with the ffmpeg that imageio-ffmpeg ships."""

from __future__ import annotations

import json
import os
import subprocess
import warnings

import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

import inkwarp
from _cli_scenes import HEIGHT, WIDTH, leftovers, mutated, write_scene
from inkwarp.cli import main

FRAMES = 4


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def decode_rgba(path, width=WIDTH, height=HEIGHT):
    """RGBA frames of a video or animation, decoded by the bundled ffmpeg (libvpx's VP9
    decoder for WebM: ffmpeg's own drops the alpha plane)."""
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error"]
    if str(path).endswith(".webm"):
        command += ["-c:v", "libvpx-vp9"]
    command += ["-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgba", "-"]
    data = subprocess.run(command, capture_output=True, check=True).stdout
    size = width * height * 4
    return [np.frombuffer(data[i:i + size], np.uint8).reshape(height, width, 4)
            for i in range(0, len(data), size)]


def png_frames(folder, count=FRAMES, first=0):
    return [np.asarray(Image.open(folder / f"frame_{i:04d}.png").convert("RGBA"))
            for i in range(first, first + count)]


@pytest.fixture(scope="module")
def transparent(tmp_path_factory):
    """The square scene on a transparent background, and its PNG frames (the reference)."""
    folder = tmp_path_factory.mktemp("transparent")
    scene = write_scene(folder, mutated(lambda d: d.update(background=[255, 255, 255, 0])))
    assert main(["render", str(scene), "-o", str(folder / "png"), "-q"]) == 0
    reference = png_frames(folder / "png")
    assert reference[0][..., 3].min() == 0 and reference[0][..., 3].max() == 255
    return scene, reference


@pytest.mark.parametrize("suffix, alpha_tolerance, colour_tolerance",
                         [(".webm", 3, 8), (".mov", 1, 2), (".apng", 0, 0)])
def test_transparent_video_keeps_the_alpha_of_the_png_render(capsys, tmp_path, transparent,
                                                              suffix, alpha_tolerance,
                                                              colour_tolerance):
    scene, reference = transparent
    out = tmp_path / f"anim{suffix}"
    code, stdout, err = run(capsys, "render", scene, "-o", out)
    assert code == 0, err
    frames = decode_rgba(out)
    assert len(frames) == FRAMES
    for got, want in zip(frames, reference):
        assert np.abs(got[..., 3].astype(int) - want[..., 3]).max() <= alpha_tolerance
        opaque = want[..., 3] == 255
        # colour where it shows (VP9's 4:2:0 chroma blurs the small square's edges)
        assert np.abs(got[opaque][:, :3].astype(int) - want[opaque][:, :3]).mean() <= colour_tolerance
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("suffix", [".mp4", ".webm", ".mov"])
def test_videos_are_bt709_and_say_so(tmp_path, suffix):
    # Untagged, ffmpeg converted by the BT.601 matrix, which players and editors assume only
    # for standard definition: an HD (200, 50, 50) came back as (212, 62, 47).
    frame = np.zeros((64, 96, 4), np.uint8)
    frame[...] = (200, 50, 50, 255)
    frame[:32] = (30, 160, 220, 255)
    out = tmp_path / f"solid{suffix}"
    with inkwarp.video.open_writer(out, fps=24, frames=3) as writer:
        for _ in range(3):
            writer.write(frame)
    probe = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(out)],
                           capture_output=True, text=True).stderr
    assert "bt709, progressive" in probe, probe  # matrix, primaries and transfer alike
    got = decode_rgba(out, 96, 64)[0]  # ffmpeg decodes by the tags
    assert np.abs(got[48, 48, :3].astype(int) - (200, 50, 50)).max() <= 3, got[48, 48]
    assert np.abs(got[8, 48, :3].astype(int) - (30, 160, 220)).max() <= 3, got[8, 48]


def test_transparent_gif_has_1_bit_alpha(capsys, tmp_path, transparent):
    scene, reference = transparent
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "anim.gif")
    assert code == 0, err
    frames = decode_rgba(tmp_path / "anim.gif")
    assert len(frames) == FRAMES
    for got, want in zip(frames, reference):
        assert set(np.unique(got[..., 3])) <= {0, 255}
        assert (got[..., 3] == np.where(want[..., 3] >= 128, 255, 0)).all()
    # The same from Python, through write_frames (it flattened the frames over white).
    from inkwarp.video import write_frames

    write_frames(tmp_path / "python.gif", inkwarp.Scene.load(scene).frames(), fps=4)
    assert (tmp_path / "python.gif").read_bytes() == (tmp_path / "anim.gif").read_bytes()


def test_a_gif_stores_a_run_of_identical_frames_once_with_its_delays_added(tmp_path):
    from inkwarp.video import write_frames

    still, moved = np.full((6, 8, 4), 255, np.uint8), np.full((6, 8, 4), 255, np.uint8)
    still[..., :3], moved[2, 3, :3] = 40, 0
    clear = still.copy()
    clear[:3, :, 3] = 0  # half of it transparent
    write_frames(tmp_path / "a.gif", [still] * 5 + [moved] + [clear] * 3 + [still], fps=24)
    frames, delays = [], []
    with Image.open(tmp_path / "a.gif") as gif:
        for i in range(gif.n_frames):
            gif.seek(i)
            frames.append(np.asarray(gif.convert("RGBA")))
            delays.append(gif.info["duration"])
    # 4, 4, 4, 5, 4 | 4 | 4, 4, 5 | 4 hundredths: 10 frames at 24 fps keep their 0.42 s.
    assert delays == [210, 40, 130, 40] and sum(delays) == round(1000 * 10 / 24, -1)
    assert [f.tolist() for f in frames] == [still.tolist(), moved.tolist(), np.where(clear[..., 3:] == 0, 0, clear).tolist(), still.tolist()]


def test_a_gif_frame_longer_than_a_gif_delay_is_repeated_to_keep_its_time(tmp_path):
    # A GIF delay is 16 bits of hundredths (655.35 s at most): a frame of 1000 s (0.001 fps)
    # stopped the render with a traceback (struct.error); a held pose past it is split too.
    from inkwarp.video import write_frames

    a, b = np.full((4, 6, 4), 255, np.uint8), np.full((4, 6, 4), 255, np.uint8)
    a[..., :3], b[..., :3] = 30, 200

    def played(name: str) -> tuple[list[int], list[int]]:
        shades, delays = [], []
        with Image.open(tmp_path / name) as gif:
            for i in range(gif.n_frames):
                gif.seek(i)
                shades.append(int(np.asarray(gif.convert("RGBA"))[0, 0, 0]))
                delays.append(gif.info["duration"])
        return shades, delays

    write_frames(tmp_path / "slow.gif", [a, b, a], fps=0.001)
    assert played("slow.gif") == ([30, 30, 200, 200, 30, 30], [500_000] * 6)  # 3000 s in all
    # Ten held frames of 100 s: 1000 s, as two even copies (not 600 s and 400 s).
    write_frames(tmp_path / "held.gif", [a] * 10 + [b], fps=0.01)
    assert played("held.gif") == ([30, 30, 200], [500_000, 500_000, 100_000])


@pytest.mark.parametrize("suffix", [".gif", ".mp4", ".webm", ".png", "/"])
@pytest.mark.parametrize("fps", [1e-9, 0, -24, 5000, float("nan")])
def test_a_writer_takes_the_rates_a_scene_may_have(tmp_path, suffix, fps):
    from inkwarp.video import open_writer

    with pytest.raises(ValueError, match=r"fps must be a number of frames per second from 0\.001 \(one frame every 1000 s\) to 1000; got "):
        open_writer(f"{tmp_path / 'out'}{suffix}", fps=fps)
    assert list(tmp_path.iterdir()) == []


def test_background_option_overrides_the_scene(capsys, tmp_path, transparent):
    scene, reference = transparent
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "f.png", "--background", "#ff0000")
    assert code == 0, err
    frame = np.asarray(Image.open(tmp_path / "f.png").convert("RGBA"))
    assert (frame[..., 3] == 255).all() and (frame[0, 0] == (255, 0, 0, 255)).all()
    opaque = write_scene(tmp_path / "opaque")  # its background is white
    code, _, err = run(capsys, "render", opaque, "-o", tmp_path / "t/", "--background",
                       "transparent", "-q")
    assert code == 0, err
    assert (png_frames(tmp_path / "t")[1][..., 3] == reference[1][..., 3]).all()
    code, _, err = run(capsys, "render", opaque, "-o", tmp_path / "x.webm", "--background", "blue-ish")
    assert code == 2 and "--background blue-ish: give transparent" in err
    assert not (tmp_path / "x.webm").exists() and leftovers(tmp_path) == []


@pytest.mark.parametrize("layout, grid", [(None, (2, 2)), ("3x2", (3, 2)), ("4", (4, 1))])
def test_sprite_sheet_json_points_at_each_frame(capsys, tmp_path, transparent, layout, grid):
    scene, reference = transparent
    args = ["--sprite-sheet"] + ([layout] if layout else [])
    code, stdout, err = run(capsys, "render", scene, "-o", tmp_path / "sheet.png", *args)
    assert code == 0, err
    sheet = np.asarray(Image.open(tmp_path / "sheet.png").convert("RGBA"))
    meta = json.loads((tmp_path / "sheet.json").read_text())
    assert meta["meta"]["image"] == "sheet.png"
    assert meta["meta"]["size"] == {"w": WIDTH * grid[0], "h": HEIGHT * grid[1]}
    assert sheet.shape == (HEIGHT * grid[1], WIDTH * grid[0], 4)
    assert list(meta["frames"]) == [f"frame_{i:04d}.png" for i in range(FRAMES)]
    for i, (name, entry) in enumerate(meta["frames"].items()):
        r = entry["frame"]
        assert (r["w"], r["h"]) == (WIDTH, HEIGHT) and entry["duration"] == 250
        assert entry["rotated"] is False and entry["trimmed"] is False
        assert entry["sourceSize"] == {"w": WIDTH, "h": HEIGHT}
        assert (sheet[r["y"]:r["y"] + r["h"], r["x"]:r["x"] + r["w"]] == reference[i]).all()


def test_sprite_sheet_too_small_is_refused_before_rendering(capsys, tmp_path, transparent):
    scene, _ = transparent
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "sheet.png", "--sprite-sheet", "1x2")
    assert code == 2 and "1x2 holds 2 frames, the render has 4" in err
    assert os.listdir(tmp_path) == []


def test_sprite_sheet_bigger_than_engines_load_is_refused_before_rendering(capsys, tmp_path,
                                                                         transparent):
    """A sheet over 16384 px a side (no engine loads it as a texture, and it is held whole in
    memory: 240 frames of 4K were 8 GB) is refused with the fix before any frame renders."""
    import inkwarp
    from inkwarp.outputs import MAX_SHEET_SIDE_PX

    scene, _ = transparent
    columns = MAX_SHEET_SIDE_PX // WIDTH + 1
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "sheet.png",
                       "--sprite-sheet", columns)
    assert code == 2, err
    assert (f"--sprite-sheet {columns}: {columns}x1 frames of {WIDTH}x{HEIGHT} make a "
            f"{columns * WIDTH}x{HEIGHT} sheet, over the 16384 px") in err
    assert "Traceback" not in err and "%" not in err and len(err.strip().splitlines()) == 1
    with pytest.raises(ValueError, match="over the 16384 px"):
        inkwarp.render(scene, tmp_path / "sheet.png", sprite_sheet=f"1x{MAX_SHEET_SIDE_PX}")
    assert os.listdir(tmp_path) == []


def test_sprite_sheet_json_that_would_replace_the_scene_is_refused(capsys, tmp_path, transparent):
    """`-o character.png --sprite-sheet` for `character.json` wrote the sheet's JSON over the
    scene itself; now it is refused before rendering, from the CLI and from Python."""
    import shutil

    import inkwarp

    scene, _ = transparent
    for name in os.listdir(scene.parent):
        if os.path.isfile(scene.parent / name):
            shutil.copy(scene.parent / name, tmp_path / name)
    own = tmp_path / scene.name
    before = own.read_bytes()
    listing = sorted(os.listdir(tmp_path))
    code, _, err = run(capsys, "render", own, "-o", own.with_suffix(".png"), "--sprite-sheet")
    assert code == 2, err
    assert f"the sprite sheet's {own.name} would replace the scene" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    with pytest.raises(ValueError, match="would replace the scene"):
        inkwarp.render(own, own.with_suffix(".png"), sprite_sheet=True)
    assert own.read_bytes() == before and sorted(os.listdir(tmp_path)) == listing
    # Another name beside it is fine.
    code, _, err = run(capsys, "render", own, "-o", tmp_path / "sheet.png", "--sprite-sheet", "-q")
    assert code == 0, err
    assert own.read_bytes() == before and (tmp_path / "sheet.json").exists()


# --- farm chunks ------------------------------------------------------------------------------

def wavy_doc():
    """40 frames of a bending spline and a moving region: warm starts matter."""
    def change(doc):
        doc.update(fps=20, duration=2.0)
        doc["features"] = [
            {"id": "bend", "kind": "spline", "rest": [[8, 20], [20, 16], [30, 20], [40, 18]],
             "keys": [{"t": 0, "points": [[8, 20], [20, 16], [30, 20], [40, 18]]},
                      {"t": 1, "points": [[8, 24], [21, 10], [31, 26], [40, 14]]},
                      {"t": 2, "points": [[8, 16], [19, 22], [29, 14], [40, 22]]}]},
            {"id": "pin", "kind": "point", "rest": [[14, 30]],
             "keys": [{"t": 0, "points": [[14, 30]]}, {"t": 2, "points": [[17, 33]]}]}]
    return mutated(change)


def test_one_frame_to_a_png_is_that_frame_of_a_sequential_render(capsys, tmp_path):
    # A farm re-renders one frame: through its warm-start chain, not from zero, so its
    # pixels are the sequence's (docs/guides/render-farm.md).
    scene = write_scene(tmp_path / "s", wavy_doc())
    # A picture of noise: a field a few thousandths of a pixel off changes its pixels.
    noise = np.random.default_rng(0).integers(0, 256, (HEIGHT, WIDTH, 4), dtype=np.uint8)
    noise[..., 3] = 255
    Image.fromarray(noise, "RGBA").save(tmp_path / "s" / "square.png")
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "seq/", "-q")
    assert code == 0, err
    sequential = png_frames(tmp_path / "seq", 40)
    cold = inkwarp.Scene.load(scene).render(frame=21)
    for index in (21, 32):
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / f"f{index}.png", "--frame", index, "-q")
        assert code == 0, err
        got = np.asarray(Image.open(tmp_path / f"f{index}.png").convert("RGBA"))
        assert np.array_equal(got, sequential[index]), index
    # Frame 21 solved from zero is a different (equally valid) answer: the chain matters.
    assert not np.array_equal(cold, sequential[21])


def test_only_warm_started_layers_need_a_pre_roll(tmp_path):
    from inkwarp import rendering

    scene = inkwarp.Scene.load(write_scene(tmp_path / "s", wavy_doc()))
    assert rendering.warm_starts(scene) and not rendering.warm_starts(scene, "triangulation")
    solved = []

    class Recording:  # the engine's scene, noting the ranges it is asked to solve
        def __init__(self, core):
            self.core = core

        def __getattr__(self, name):
            return getattr(self.core, name)

        def frames(self, start, stop, *rest):
            solved.append((start, stop))
            return self.core.frames(start, stop, *rest)

    scene._core = Recording(scene._core)
    assert [i for i, _ in rendering.render_range(scene, 21, 23, method="triangulation")] == [21, 22]
    assert [i for i, _ in rendering.render_range(scene, 21, 23)] == [21, 22]
    frames = scene.frames(21, 23)
    assert len(frames) == 2 and frames.index == 20
    assert solved == [(21, 23), (16, 23), (16, 23)]
    # A range past the last frame is empty, as the frames are.
    assert list(rendering.render_range(scene, 45, 47)) == []


def test_scene_frames_from_inside_a_chain_are_those_of_a_sequential_render(tmp_path):
    # Scene.frames pre-rolls as `inkwarp render --frames` and inkwarp.render(frames=) do.
    folder = tmp_path / "s"
    path = write_scene(folder, wavy_doc())
    noise = np.random.default_rng(0).integers(0, 256, (HEIGHT, WIDTH, 4), dtype=np.uint8)
    noise[..., 3] = 255
    Image.fromarray(noise, "RGBA").save(folder / "square.png")
    scene = inkwarp.Scene.load(path)
    sequential = list(scene.frames(0, 34))
    part = scene.frames(20, 34)
    assert len(part) == 14
    got = list(part)
    assert len(got) == 14 and part.index == 33
    for i, frame in enumerate(got, 20):
        np.testing.assert_array_equal(frame, sequential[i], err_msg=f"frame {i}")
    # Started cold at frame 20, the frames differ: the pre-roll is what makes them equal.
    assert not np.array_equal(scene.render(frame=20), sequential[20])


def test_chunked_and_skip_existing_renders_equal_a_sequential_one(capsys, tmp_path):
    scene = write_scene(tmp_path / "s", wavy_doc())
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "seq/", "-q")
    assert code == 0, err
    sequential = png_frames(tmp_path / "seq", 40)
    for chunk in ("0:13", "13:29", "29:40"):  # chunks that start inside warm-start chains
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / "chunks/", "--frames",
                           chunk, "--skip-existing", "-q")
        assert code == 0, err
    for got, want in zip(png_frames(tmp_path / "chunks", 40), sequential):
        assert np.abs(got.astype(int) - want).max() <= 1
    # A second pass over a part already there renders nothing and touches nothing.
    stamp = os.stat(tmp_path / "chunks" / "frame_0020.png").st_mtime_ns
    code, stdout, _ = run(capsys, "render", scene, "-o", tmp_path / "chunks/", "--frames",
                          "0:40", "--skip-existing")
    assert code == 0 and "wrote 0 new frames of 0:40" in stdout and "40 already there" in stdout
    assert os.stat(tmp_path / "chunks" / "frame_0020.png").st_mtime_ns == stamp
    # Holes are filled: delete two frames and render the whole range again.
    for i in (7, 33):
        (tmp_path / "chunks" / f"frame_{i:04d}.png").unlink()
    code, stdout, _ = run(capsys, "render", scene, "-o", tmp_path / "chunks/", "--skip-existing")
    assert code == 0 and "wrote 2 new frames" in stdout
    for i in (7, 33):
        got = np.asarray(Image.open(tmp_path / "chunks" / f"frame_{i:04d}.png").convert("RGBA"))
        assert np.abs(got.astype(int) - sequential[i]).max() <= 1
    # A frame of another size there (another render's, copied in) is no frame of this
    # scene: rendered again, not kept as done.
    Image.new("RGBA", (8, 6), (255, 0, 0, 255)).save(tmp_path / "chunks" / "frame_0011.png")
    code, stdout, _ = run(capsys, "render", scene, "-o", tmp_path / "chunks/", "--skip-existing")
    assert code == 0 and "wrote 1 new frame" in stdout, stdout
    got = np.asarray(Image.open(tmp_path / "chunks" / "frame_0011.png").convert("RGBA"))
    assert got.shape == sequential[11].shape and np.abs(got.astype(int) - sequential[11]).max() <= 1
    assert leftovers(tmp_path / "chunks") == []


def test_a_shorter_render_into_a_folder_names_the_frames_left_past_its_end(capsys, tmp_path):
    # A shot shortened and rendered again into its folder: the earlier render's last frames
    # stay (other files are left alone), and a join of the folder's frames would take them.
    doc = wavy_doc()
    long = write_scene(tmp_path / "long", doc)
    code, _, err = run(capsys, "render", long, "-o", tmp_path / "shot/", "-q")
    assert code == 0 and "past this scene" not in err, err
    doc["duration"] = 1.0
    short = write_scene(tmp_path / "short", doc)
    for extra in ([], ["--skip-existing"]):
        code, _, err = run(capsys, "render", short, "-o", tmp_path / "shot/", "-q", *extra)
        assert code == 0 and "frame_0020.png and maybe more, from an earlier render, lie past this scene's last frame (19)" in err, err
    # A chunk that stops before the end says nothing: the frames after it are the shot's.
    code, _, err = run(capsys, "render", long, "-o", tmp_path / "shot/", "--frames", "0:10", "-q")
    assert code == 0 and "past this scene" not in err, err


def test_skip_existing_leaves_frames_another_chunk_writes_meanwhile(capsys, tmp_path, monkeypatch):
    # Two farm chunks over the same frames: each frame is checked just before it is
    # rendered and written, so frames the other chunk wrote meanwhile are neither rendered
    # nor replaced, and the summary counts them as already there.
    from inkwarp import rendering

    scene = write_scene(tmp_path / "s", wavy_doc())
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "seq/", "-q")
    assert code == 0, err
    out = tmp_path / "frames"
    real = rendering.render_range
    solved = []

    def other_chunk(*indices):
        for i in indices:
            (out / f"frame_{i:04d}.png").write_bytes((tmp_path / "seq" / f"frame_{i:04d}.png").read_bytes())
        return {i: os.stat(out / f"frame_{i:04d}.png").st_ino for i in indices}

    theirs = {}

    def render_range(scene, start, stop, **options):
        for index, frame in real(scene, start, stop, **options):
            solved.append(index)
            if index == 10:  # the other chunk writes frames 11 to 29 while this one renders 10
                theirs.update(other_chunk(*range(11, 30)))
            if index == 35:  # and frame 35 while this one renders it
                theirs.update(other_chunk(35))
            yield index, frame

    monkeypatch.setattr(rendering, "render_range", render_range)
    code, stdout, err = run(capsys, "render", scene, "-o", f"{out}/", "--frames", "0:40",
                            "--skip-existing")
    assert code == 0, err
    assert "wrote 20 new frames of 0:40" in stdout and "(20 already there)" in stdout
    assert not set(range(11, 30)) & set(solved)
    assert {i: os.stat(out / f"frame_{i:04d}.png").st_ino for i in theirs} == theirs
    for got, want in zip(png_frames(out, 40), png_frames(tmp_path / "seq", 40)):
        assert np.abs(got.astype(int) - want).max() <= 1
    assert leftovers(out) == []


def test_skip_existing_renders_empty_and_cut_off_frame_files_again(capsys, tmp_path):
    from inkwarp.rendering import frame_file_complete

    scene = write_scene(tmp_path / "s")
    out = tmp_path / "frames"
    code, _, err = run(capsys, "render", scene, "-o", f"{out}/", "-q")
    assert code == 0, err
    whole = (out / "frame_0001.png").read_bytes()
    (out / "frame_0000.png").write_bytes(b"")
    (out / "frame_0002.png").write_bytes(whole[: len(whole) // 2])
    (out / "frame_0003.png").write_bytes(b"not a picture at all")
    kept = os.stat(out / "frame_0001.png").st_mtime_ns
    assert [frame_file_complete(out / f"frame_{i:04d}.png") for i in range(4)] == [False, True, False, False]
    code, stdout, err = run(capsys, "render", scene, "-o", f"{out}/", "--skip-existing")
    assert code == 0, err
    assert "wrote 3 new frames of 0:4" in stdout and "(1 already there)" in stdout
    assert all(frame_file_complete(out / f"frame_{i:04d}.png") for i in range(4))
    assert os.stat(out / "frame_0001.png").st_mtime_ns == kept
    reference = tmp_path / "ref"
    assert main(["render", str(scene), "-o", str(reference), "-q"]) == 0
    for got, want in zip(png_frames(out), png_frames(reference)):
        assert np.array_equal(got, want)


def test_frames_go_into_a_writable_folder_whose_parent_is_read_only(capsys, tmp_path, monkeypatch):
    # A farm's writable frames/ inside a shot folder only an admin may write to: the
    # frames are gathered inside frames/ itself. (The tests run as root, whom permissions
    # do not stop, so the shot folder refuses here by its access check and by mkdir.)
    from pathlib import Path

    scene = write_scene(tmp_path / "s")
    shot = tmp_path / "shot"
    out = shot / "frames"
    out.mkdir(parents=True)
    access, mkdir, opened = os.access, os.mkdir, os.open
    locked = lambda path: Path(path).absolute().parent == shot and Path(path).absolute() != out  # noqa: E731

    def refused(path):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(os, "access", lambda path, mode, **kw: False if Path(path) == shot and mode & os.W_OK
                        else access(path, mode, **kw))
    monkeypatch.setattr(os, "mkdir", lambda path, *a, **kw: refused(path) if locked(path) else mkdir(path, *a, **kw))
    monkeypatch.setattr(os, "open", lambda path, *a, **kw: refused(path) if locked(path) else opened(path, *a, **kw))
    for args in ([], ["--frames", "0:2", "--skip-existing"]):
        code, _, err = run(capsys, "render", scene, "-o", f"{out}/", "-q", *args)
        assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == [f"frame_{i:04d}.png" for i in range(FRAMES)]
    assert sorted(p.name for p in shot.iterdir()) == ["frames"]


def test_skip_existing_needs_a_directory(capsys, tmp_path):
    scene = write_scene(tmp_path / "s")
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.mp4", "--skip-existing")
    assert code == 2 and "--skip-existing works with a directory" in err


@pytest.mark.parametrize("command", [["new", "{folder}/square.png", "--embed"], ["schema"],
                                     ["field", "{scene}", "--time", "0.5"], ["frame", "{video}", "--frame", "0"]])
def test_a_full_disk_names_the_output_of_every_command(tmp_path, command):
    # Files written whole by a library (json, numpy, PIL) fail without a file name; the
    # message names the command's output, as render's does, and nothing is left.
    import resource
    import sys

    folder = tmp_path / "s"
    scene = write_scene(folder)
    noise = np.random.default_rng(0).integers(0, 256, (HEIGHT, WIDTH, 4), dtype=np.uint8)
    noise[..., 3] = 255
    Image.fromarray(noise, "RGBA").save(folder / "square.png")
    video = tmp_path / "clip.mp4"
    assert main(["render", str(scene), "-o", str(video), "-q"]) == 0
    out = tmp_path / "out"
    out.mkdir()
    suffix = {"new": ".json", "schema": ".json", "field": ".npy", "frame": ".png"}[command[0]]
    target = out / f"result{suffix}"
    args = [a.format(folder=folder, scene=scene, video=video) for a in command]

    def limited():
        resource.setrlimit(resource.RLIMIT_FSIZE, (1024, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))

    result = subprocess.run([sys.executable, "-m", "inkwarp.cli", *args, "-o", str(target)], capture_output=True,
                            text=True, preexec_fn=limited, cwd=tmp_path, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    assert result.returncode == 1, result.stderr
    assert result.stderr.strip() == (f"inkwarp {command[0]}: error: {target}: the file could not be written (File too "
                                     "large); the file system's or the process's file-size limit (ulimit -f) allows no "
                                     "more; raise the limit or write the output to another disk"), result.stderr
    assert list(out.iterdir()) == []


def test_a_full_standard_output_is_named_as_such(tmp_path):
    # `inkwarp render ... > /dev/full`: the GIF is written; what failed is the report.
    import sys

    scene = write_scene(tmp_path / "s")
    with open("/dev/full", "w") as full:
        result = subprocess.run([sys.executable, "-m", "inkwarp.cli", "render", str(scene), "-o",
                                 str(tmp_path / "a.gif")], stdout=full, stderr=subprocess.PIPE, text=True)
    assert result.returncode == 1
    assert result.stderr.strip().splitlines()[-1] == (
        "inkwarp render: error: standard output could not be written (No space left on device); free space on that "
        "disk or write the output to another one"), result.stderr
    assert (tmp_path / "a.gif").stat().st_size > 0
    # Started without a standard output at all (`>&-`), a command works and says nothing.
    closed = subprocess.run(["sh", "-c", f'"{sys.executable}" -m inkwarp.cli validate "{scene}" >&-'],
                            stderr=subprocess.PIPE, text=True)
    assert closed.returncode == 0 and closed.stderr == "", closed.stderr


@pytest.mark.parametrize("output, args", [
    ("out.mp4", []), ("out.webm", []), ("out.mov", []), ("out.apng", []), ("out.gif", []),
    ("clear.gif", ["--background", "transparent"]), ("frames/", []),
    ("chunk/", ["--skip-existing"]), ("sheet.png", ["--sprite-sheet"])])
def test_a_full_disk_is_one_message_naming_the_output_for_every_format(tmp_path, output, args):
    # A file-size limit (ulimit -f) fails writes as a full disk does, at the same places.
    import resource
    import sys

    folder = tmp_path / "s"
    scene = write_scene(folder, mutated(lambda d: d.update(duration=3.0)))  # 12 frames
    noise = np.random.default_rng(0).integers(0, 256, (HEIGHT, WIDTH, 4), dtype=np.uint8)
    noise[..., 3] = 255  # incompressible: every output is over the limit
    Image.fromarray(noise, "RGBA").save(folder / "square.png")
    out = tmp_path / "out"
    out.mkdir()
    limit = 2048

    def limited():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))

    result = subprocess.run([sys.executable, "-m", "inkwarp.cli", "render", str(scene), "-o",
                             f"{out}/{output}", "-q", *args], capture_output=True, text=True,
                            preexec_fn=limited, cwd=tmp_path,
                            env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    assert result.returncode == 1, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    name = output.rstrip("/")
    written = f"{out / name}" + ("/frame_0000.png" if output.endswith("/") else "")
    assert lines[0].startswith(f"inkwarp render: error: {written}: the file could not be "
                               "written (File too large); "), lines[0]
    assert "ulimit -f" in lines[0]
    assert leftovers(out) == [] and [p.name for p in out.iterdir()] == (
        ["chunk"] if output == "chunk/" else [])
    if output == "chunk/":
        assert list((out / "chunk").iterdir()) == []


@pytest.mark.parametrize("options, message", [
    ({"frames": "5:1"}, "frames='5:1' is not a range of the scene, which has frames 0 to 3"),
    ({"frames": (4, 99)}, "frames=(4, 99) is not a range of the scene, which has frames 0 to 3"),
    ({"background": "nope"}, "background='nope': give transparent"),
    # Levels 0 to 1 were cut to [0, 0, 0, 1]; NaN and None raised int()'s own errors.
    ({"background": [0.5, 0.5, 0.5, 1.0]}, "background=[0.5, 0.5, 0.5, 1.0] is not a colour; give four "
     "integers 0 to 255, [R, G, B, A] (or a colour such as 'transparent' or '#RRGGBB'); for levels 0 to 1, "
     "scale them: [round(v * 255) for v in background]"),
    ({"background": [float("nan")] * 4}, "background=[nan, nan, nan, nan] is not a colour; give four integers"),
    ({"background": [None] * 4}, "background=[None, None, None, None] is not a colour; give four integers"),
    # As a scene's background: whole numbers written as floats, and booleans, are refused too.
    ({"background": [255.0] * 4}, "background=[255.0, 255.0, 255.0, 255.0] is not a colour"),
    ({"background": [0, 0, 0, 256]}, "background=[0, 0, 0, 256] is not a colour"),
    ({"background": [255, 0, 0]}, "background=[255, 0, 0] is not a colour"),
    ({"background": [True, 0, 0, 255]}, "background=[True, 0, 0, 255] is not a colour"),
    ({"sprite_sheet": "0x1"}, "sprite_sheet='0x1': columns and rows must be at least 1"),
    ({"sprite_sheet": "1x1"}, "sprite_sheet='1x1': 1x1 holds 1 frame, the render has 4; give "
                              "more rows or columns, or pick fewer with frames=(A, B)"),
    ({"skip_existing": True}, "skip_existing=True works with a directory")])
def test_python_callers_see_argument_names_not_flags(tmp_path, options, message):
    scene = write_scene(tmp_path / "s")
    output = tmp_path / ("sheet.png" if "sprite_sheet" in options else "a.gif")
    with pytest.raises(ValueError) as caught:
        inkwarp.render(str(scene), output, **options)
    assert message in str(caught.value) and "--" not in str(caught.value)
    assert list(tmp_path.iterdir()) == [tmp_path / "s"]


def test_python_takes_a_background_of_four_integers(tmp_path, transparent):
    scene, _ = transparent
    for i, background in enumerate(([255, 0, 0, 255], np.array([0, 0, 255, 255], np.uint8))):
        inkwarp.render(str(scene), tmp_path / f"f{i}", frames=(0, 1), background=background)
        assert png_frames(tmp_path / f"f{i}", count=1)[0][0, 0].tolist() == list(background)


def test_the_command_line_names_its_flags(capsys, tmp_path):
    scene = write_scene(tmp_path / "s")
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "sheet.png", "--sprite-sheet", "1x1")
    assert code == 2 and "--sprite-sheet 1x1: 1x1 holds 1 frame" in err and "with --frames" in err
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif", "--frames", "5:1")
    assert code == 2 and "--frames 5:1 is not a range of the scene, which has frames 0 to 3" in err


def test_an_mp4_of_frames_with_transparent_pixels_warns_once_with_the_formats_that_keep_alpha(capsys, tmp_path, transparent):
    # Only frames that show the transparent background count: a picture that covers the
    # whole frame (a photograph) renders to an .mp4 without a word.
    scene, reference = transparent
    count = sum(int(f[..., 3].min() < 255) for f in reference)
    assert count == len(reference) > 1
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.mp4", "-q")
    assert code == 0 and (tmp_path / "a.mp4").exists()
    assert err == (f"inkwarp render: warning: a.mp4: {count} of its {count} frames had transparent "
                   "pixels, flattened over white (an .mp4 has no alpha); for alpha render a .webm, "
                   ".mov, .apng or a directory of PNGs, or give the scene an opaque background\n")
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "b.mp4", "-q", "--background", "white")
    assert code == 0 and err == ""
    with pytest.warns(inkwarp.InkwarpWarning, match=r"b\.mp4: 1 of its 1 frames had transparent pixels") as caught:
        inkwarp.render(str(scene), tmp_path / "b.mp4", frames=(2, 3), background="transparent")
    assert len(caught) == 1
    opaque = write_scene(tmp_path / "opaque")
    code, _, err = run(capsys, "render", opaque, "-o", tmp_path / "c.mp4", "-q")
    assert code == 0 and err == ""


def test_an_mp4_of_a_nearly_opaque_edge_says_nothing(tmp_path):
    # An opaque photograph with a held border beside a large move comes out with its outer
    # pixels at alpha 252-254 (the surface squeezed at the edge); over white they change
    # by at most 3 levels, and the MP4 is written without a word. A pixel really see-through
    # is still named.
    from inkwarp.video import open_writer

    frame = np.full((16, 16, 4), 200, np.uint8)
    frame[..., 3] = 255
    frame[:, -1, 3] = 252
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with open_writer(tmp_path / "edge.mp4", fps=24) as writer:
            writer.write(frame)
    frame[3, 3, 3] = 249
    with pytest.warns(inkwarp.InkwarpWarning, match="1 of its 1 frames had transparent pixels"):
        with open_writer(tmp_path / "see.mp4", fps=24) as writer:
            writer.write(frame)


@pytest.mark.parametrize("command, hint", [
    (["render", "{scene}"], "name the file or directory to write, such as out.mp4 or frames/"),
    (["schema"], "leave -o out to print the schema")])
def test_o_dash_is_refused_not_made_a_folder_named_dash(capsys, tmp_path, monkeypatch, command, hint):
    scene = write_scene(tmp_path / "s")
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *[a.format(scene=scene) for a in command], "-o", "-")
    assert code == 2 and out == ""
    assert err == (f"inkwarp {command[0]}: error: -o -: inkwarp {command[0]} writes files, not "
                   f"standard output; {hint}\n")
    assert not (tmp_path / "-").exists()


def test_ray_workers_fit_each_nodes_cpus_and_memory():
    """How many render workers a Ray cluster holds: per live node the fewer of its CPUs
    and its memory over the scene's; none at all is a clear error naming the fix."""
    from inkwarp.rendering import ray_workers

    gib = 1 << 30
    node = lambda cpus, mem, alive=True: {"Alive": alive, "Resources": {"CPU": cpus, "memory": mem * gib}}
    assert ray_workers([node(16, 64)], 2 * gib) == 16
    assert ray_workers([node(16, 10)], 3 * gib) == 3
    assert ray_workers([node(2, 8), node(8, 8), node(8, 100, alive=False)], 4 * gib) == 4
    with pytest.raises(ValueError, match=r"about 12\.0 GiB of memory a worker.*the largest has "
                                         r"8\.0 GiB.*grid_step"):
        ray_workers([node(8, 8), node(4, 2)], 12 * gib)
    with pytest.raises(ValueError, match="no live node"):
        ray_workers([node(8, 100, alive=False)], gib)


def test_the_writers_docs_name_every_kind_they_write():
    # open_writer's docstring named .png, a directory, .gif and .mp4 only, and its `kind`
    # four of the seven kinds, though it writes .webm, .mov and .apng too.
    import re
    from typing import get_args

    from inkwarp import video

    for function in (video.open_writer, video.output_kind):
        for suffix in video.FILE_SUFFIXES:
            assert f"``{suffix}``" in function.__doc__, (function.__name__, suffix)
    kinds = re.search(r"kind : \{(.*?)\}", video.open_writer.__doc__).group(1)
    assert {k.strip().strip('"') for k in kinds.split(",")} == set(get_args(video.OutputKind))
    assert "SpriteSheetWriter" in video.open_writer.__doc__
