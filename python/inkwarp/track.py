"""Tracking a drawing through a video (DESIGN §11): the first half of the paper's
actor-to-cat pipeline.

A scene's drawing is traced over one frame ``K`` of a video (its features' ``rest``
geometry). :func:`track_dict` follows every feature through the footage and gives the
scene a key at every video frame (``t = k / fps``); :func:`inkwarp.transfer` then carries
the performance onto another picture.

How a feature is followed
-------------------------
Each feature is tracked through its control points and through samples along its curve
(every :data:`SAMPLE_SPACING_PX` pixels of arc length, from :func:`inkwarp.sample`). From
one frame to the next, every such point is

1. moved by OpenCV's dense DIS optical flow (``cv2.DISOpticalFlow``), which gives every
   pixel a motion, textured or not;
2. refined by pyramidal Lucas–Kanade started from the DIS estimate, and checked forward
   and backward (the point tracked back must land where it started);
3. re-registered against the anchor frame it started from (Lucas–Kanade from the anchor's
   picture straight to the new frame, started at the estimate and checked both ways), so
   that where the picture still looks as it did, the track does not drift;
4. kept where the texture under it (the smaller eigenvalue of the structure tensor) and
   its forward–backward check say Lucas–Kanade can see it; elsewhere — flat skin, a
   smooth gradient, an occluded spot — it is placed by the continuous thin plate
   (:class:`inkwarp.ThinPlateMap`) fitted from the anchor positions of the trusted points
   to where they are now: the drawing's own smoothness prior regularises the rest of it;
5. checked against its curve's neighbours (the feature's points within 10 px): a point
   whose move from the last frame is more than ``lost_px`` from theirs, where they agree
   within half of that, is placed by the thin plate too, however well its own checks pass
   (its window straddles the edge of what moves and holds to what stays still), unless the
   anchor's few pixels around it (:data:`ODD_WINDOW_PX`) match the frame better where it is
   than where its neighbours' move would take it (it stays beside what moves away).

Keys the scene already has are **corrections**: the drawing is tracked from each of
them, forward and backward, as from frame ``K``, and between two anchors of a feature
the two tracks are blended linearly in time, so the result passes through every key.

A feature is **lost** at a frame when the median forward–backward error of its points is
over ``lost_px``: a textured point's error is the smaller of its two Lucas–Kanade checks,
infinite where it is out of the picture or on no texture (once lost it stays lost until
the anchor registration confirms it again, tried also where it was last seen), an
untextured point's that of the dense flow, infinite where it is placed more than
``lost_px`` off the picture; a gap of at most :data:`REFOUND_FRAMES` frames between two
frames where a feature is lost counts as lost too, and so do the frames beside a lost
stretch where a point not yet found again strays from its feature (:func:`_stray_after`).
A :class:`~inkwarp.InkwarpWarning` names the features and the frames. Between two anchors,
a track that has lost the feature at a frame gives way to the other's; else the two
tracks' errors are blended as their places are. At a frame where it is named lost, a
feature keeps the shape it has at the frames around, moved by its points whose checks
passed (see :func:`_kept_in_shape`). Points of a feature that lie off the picture where
traced are named apart and judged by nothing (nothing there can be seen).

The video's grey frames are held in memory (1 byte per pixel per frame).
"""

from __future__ import annotations

import json
import math
import os
import re
import warnings
from collections.abc import Callable, Container, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp.drawing import off_picture
from inkwarp.errors import InkwarpWarning, InputError, MissingFileError, caller_outside

__all__ = ["Video", "read_video", "read_frame", "track", "track_dict", "simplify_keys",
           "SAMPLE_SPACING_PX"]

#: Arc length between the samples tracked along a curve, in pixels.
SAMPLE_SPACING_PX = 4.0

#: Lucas–Kanade window (pixels, square) and pyramid levels. Every call starts from an
#: estimate (the dense flow's, or the last position), so one level above the picture is
#: enough; with three, a window 8 times as wide on the coarsest saw changes far from the
#: point (a bar appearing 80 px away) and failed, naming a point tracked to 0.01 px lost.
LK_WINDOW_PX = 21
LK_LEVELS = 1

#: A point is trusted when its forward–backward error is under this (pixels) ...
TRUST_FB_PX = 0.5
#: ... and the smaller structure-tensor eigenvalue under it (``cv2.cornerMinEigenVal`` of
#: the grey frame scaled to 0..1, block 7) is over this.
TRUST_MIN_EIG = 5e-5

#: A registration to the anchor frame may move a point this far from the frame-to-frame
#: estimate (pixels): how much drift it can take back.
REGAIN_PX = 10.0

#: The window (pixels, square) that decides between a point and the neighbours along its curve
#: that disagree with it: small, so that it sees the point's own side of an object's edge.
ODD_WINDOW_PX = 7

#: A lost point is found again only where its window correlates with the anchor's at least
#: this much (two unrelated textures: at most 0.45; the same one 10° turned 0.7, 15° 0.47,
#: 20 % larger 0.75, darker or lighter 1).
REGAIN_LIKENESS = 0.5

#: A curve's points that move from one frame to the next farther than this from their
#: feature's affine move are not trusted (a stretch jumped a period of a repeating texture);
#: within it, a fast blink or a bending curve.
JUMP_PX = 5.0

#: The largest correction of the thin plate's placement of an untrusted point that the
#: dense flow from the warped anchor picture may make (pixels).
RESIDUAL_PX = 2.0

#: At most this many trusted points fit the regularising thin plate (evenly spread), at
#: most one in each square of this side (pixels).
TPS_POINTS = 160
TPS_CELL_PX = 12.0


def _cv2() -> Any:
    try:
        import cv2
    except ImportError:  # pragma: no cover - the [track] extra is missing
        raise InputError("inkwarp track needs OpenCV: pip install 'inkwarp[track]' "
                         "(opencv-contrib-python-headless)") from None
    return cv2


# ---- video input ------------------------------------------------------------------------

@dataclass
class Video:
    """A decoded video: grey frames (``uint8``, ``(H, W)`` each) and its frame rate."""

    path: str
    fps: float
    width: int
    height: int
    frames: list[np.ndarray] = field(repr=False)

    def __len__(self) -> int:
        return len(self.frames)


#: The decoder's address ffmpeg puts before its messages (``[h264 @ 0x55d0...]``): not for a user.
_DECODER_ADDRESS = re.compile(r"\[[^]]*@ 0x[0-9a-f]+\] *")


def _no_frames(path: str) -> ValueError:
    return ValueError(f"{path}: the video has no frames (it is empty, or cut short before its first "
                      "frame); export or copy it again")


def _unreadable(path: str, reason: str) -> ValueError:
    # A video that ends before its first frame: ffmpeg's words for it, per container.
    if re.search(r"received no packets|Nothing was written|End of file|^Duration: N/A", str(reason)):
        return _no_frames(path)
    reason = _DECODER_ADDRESS.sub("", " ".join(str(reason).split()))
    if len(reason) > 160:
        reason = reason[:157] + "..."
    return ValueError(f"{path}: cannot be read as a video ({reason}); give a video file that "
                      "ffmpeg decodes, such as an .mp4")


#: The highest time base rate taken as a video's frame rate (frames per second).
MAX_TIME_BASE_FPS = 240.0


def _probe(path: str | os.PathLike[str]) -> tuple[str, float, int, int, int | None, float | None]:
    """``(path, fps, width, height, frames, rate)`` of a video (``frames``: as many as its
    header's duration holds at that rate, None where it gives none; ``rate``: ``fps``
    where its frames must be decoded at their average rate, with a warning saying so, else
    None), or a ValueError naming it."""
    import imageio_ffmpeg

    name = os.fspath(path)
    if not os.path.exists(name):
        raise MissingFileError(2, "No such file or directory", name)
    if os.path.isdir(name):
        raise IsADirectoryError(21, "is a directory, not a video", name)
    import subprocess

    done = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-hide_banner", "-i", name],
                          capture_output=True, stdin=subprocess.DEVNULL)
    log = done.stderr.decode(errors="replace")
    stream = next((line for line in log.splitlines()
                   if re.search(r"Stream #.*: Video:", line)), None)
    if stream is None:
        if re.search(r"Stream #.*: Audio:", log):  # a sound file, or a video's sound alone
            raise InputError(f"{name}: has sound but no video stream; give the video itself "
                             "(any format ffmpeg decodes, such as an .mp4)")
        lines = [line.strip() for line in log.splitlines() if line.strip()
                 and "At least one output file" not in line]
        raise _unreadable(name, lines[-1] if lines else "ffmpeg found no video stream")
    size = re.search(r", (\d+)x(\d+)[ ,]", stream)
    average = re.search(r", ([\d.]+) fps", stream)
    base = re.search(r", ([\d.]+)(k?) tbr", stream)
    rate = average or base
    if size is None or rate is None or not float(rate.group(1)) > 0:
        raise _unreadable(name, "ffmpeg finds no frame size or frame rate in it")
    width, height, fps = int(size.group(1)), int(size.group(2)), float(rate.group(1))
    # ffmpeg hands frames on at the time base's rate ("tbr"): where frames come at uneven
    # times (a phone's variable frame rate, a GIF's delays) it repeats some, and frame k is
    # at k / tbr, not at k over the average rate ("fps"). A rate past any video's (timestamps
    # in milliseconds: "1k tbr") is no frame rate: the frames are then taken at the average.
    tbr = float(base.group(1)) * (1000 if base.group(2) else 1) if base else fps
    variable = tbr > MAX_TIME_BASE_FPS and average is not None and abs(tbr - fps) > 0.01 * fps
    if tbr <= MAX_TIME_BASE_FPS:
        fps = tbr
    # A coarse time base (milliseconds, as in every Matroska or WebM file) that ffmpeg took
    # an even rate from: the frames' own times say whether some come faster than that rate,
    # whose frames ffmpeg would drop without a word. They are then taken at their fastest
    # steady rate (a run of frames, not one early frame), repeated where it runs slower.
    tbn = re.search(r", ([\d.]+)(k?) tbn", stream)
    if not variable and tbn and float(tbn.group(1)) * (1000 if tbn.group(2) else 1) <= 1000:
        gaps, tick = _frame_gaps(name)
        fastest = None if gaps is None else _fastest_gap(gaps, tick)
        if fastest is not None and gaps.max() > 1.5 * gaps.min() + 2 * tick and 1.01 * fps < 1 / fastest <= MAX_TIME_BASE_FPS:
            tbr, fps, variable = 1 / float(np.mean(gaps)), 1 / fastest, True
    took = re.search(r"Duration: (\d+):(\d\d):(\d\d(?:\.\d+)?)", log)
    seconds = 3600 * int(took.group(1)) + 60 * int(took.group(2)) + float(took.group(3)) if took else None
    fps = _exact_rate(fps)
    if variable and tbr < fps:  # taken at its fastest rate: every frame kept
        warnings.warn(f"{name}: its frame rate varies (up to {fps:g} fps, on average {tbr:.4g}); its frames are "
                      f"taken at an even {fps:g} fps, repeated where it runs slower, so that frame k is at "
                      f"{1 / fps:.4g} k s", InkwarpWarning, stacklevel=caller_outside())
    elif variable:
        warnings.warn(f"{name}: its frame rate varies (on average {fps:g} fps, on a time base of {tbr:g}); "
                      f"its frames are taken at an even {fps:g} fps, repeated or skipped where it runs slower "
                      f"or faster, so that frame k is at {1 / fps:.4g} k s. To keep every frame, convert it to "
                      f"a constant rate first: ffmpeg -i {Path(name).name} -fps_mode cfr -r 60 constant.mp4",
                      InkwarpWarning, stacklevel=caller_outside())
    return name, fps, width, height, round(seconds * fps) if seconds else None, fps if variable else None


def _frame_gaps(name: str) -> tuple[np.ndarray | None, float]:
    """The seconds between a video's frames in time order, from its packets' timestamps
    (read without decoding), or None where ffmpeg gives fewer than three; and the time
    base's tick (the timestamps' rounding)."""
    import subprocess

    import imageio_ffmpeg

    done = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-v", "error", "-i", name, "-map", "0:v:0",
                           "-c", "copy", "-f", "framecrc", "-"], capture_output=True, stdin=subprocess.DEVNULL)
    text = done.stdout.decode(errors="replace")
    base = re.search(r"^#tb 0: (\d+)/(\d+)", text, flags=re.M)
    # Packets without a timestamp (-2⁶³, as some AVIs' B-frames) say nothing; repeated ones neither.
    times = np.unique([t for line in text.splitlines() if line.startswith("0,")
                       for t in [int(line.split(",")[2])] if t > -2**62])
    if base is None or len(times) < 3:
        return None, 0.0
    tick = int(base.group(1)) / int(base.group(2))
    return np.diff(times) * tick, tick


def _fastest_gap(gaps: np.ndarray, tick: float) -> float | None:
    """The time between frames where they come fastest: the mean gap over the longest run
    of gaps within 1.5 ticks of the shortest (timestamps rounded to ticks alternate), or
    None where that run is too short to be a rate (5 gaps, and a tenth of them all): one
    early frame is no faster rate."""
    fast = np.concatenate([[False], gaps <= gaps.min() + 1.5 * tick, [False]])
    edges = np.flatnonzero(np.diff(fast.astype(int)))
    start, stop = max(zip(edges[::2], edges[1::2]), key=lambda run: run[1] - run[0])
    if stop - start < max(5, len(gaps) / 10):
        return None
    return float(np.mean(gaps[start:stop]))


def _exact_rate(fps: float) -> float:
    """The frame rate ffmpeg prints rounded (29.97, 23.98, 59.94) as the NTSC rate it
    stands for (30000/1001 ...), so that a scene tracked from such a video, and the video
    rendered from it, keep the source's exact rate; any other rate as printed."""
    whole = round(fps * 1.001)
    if fps != int(fps) and whole in (24, 30, 48, 60, 120) and abs(fps - whole / 1.001) < 0.006:
        return whole * 1000 / 1001
    return fps


def _decode(name: str, pix_fmt: str, *, frames: int | None = None, promised: int | None = None,
            size: int = 1, rate: float | None = None) -> bytes:
    """Raw frames from ffmpeg (the first ``frames`` of them, or all; at an even ``rate``
    where given, frames repeated or skipped to keep their times). A file that decodes with
    errors into fewer frames of ``size`` bytes than the ``promised`` ones (its header's) is
    damaged or cut short: a ValueError naming it; with errors but every frame, a warning."""
    import subprocess

    import imageio_ffmpeg

    from inkwarp.video import ffmpeg_rate

    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-v", "error", "-i", name]
    if rate is not None:
        cmd += ["-r", ffmpeg_rate(rate)]
    if frames is not None:
        cmd += ["-frames:v", str(frames)]
    cmd += ["-f", "rawvideo", "-pix_fmt", pix_fmt, "-"]
    done = subprocess.run(cmd, capture_output=True, stdin=subprocess.DEVNULL)
    said = [line.strip() for line in done.stderr.decode(errors="replace").splitlines() if line.strip()]
    if done.returncode != 0:
        raise _unreadable(name, said[-1] if said else f"ffmpeg exited with {done.returncode}")
    wanted = promised if frames is None else min(frames, promised or frames)
    first = _DECODER_ADDRESS.sub("", said[0])[:120] if said else ""
    if said and wanted and len(done.stdout) // size < wanted - 1:
        raise InputError(f"{name}: damaged or cut short: ffmpeg decoded {len(done.stdout) // size} "
                         f"frames, with errors, of the {promised} its header gives ({first}); "
                         "copy or export the video again")
    if said:
        warnings.warn(f"{name}: ffmpeg found errors while decoding it ({first}); some frames "
                      "may be damaged (smeared or frozen): look at them, or copy or export the video "
                      "again", InkwarpWarning, stacklevel=caller_outside())
    return done.stdout


def read_video(path: str | os.PathLike[str]) -> Video:
    """Decode a video into grey frames (through the ffmpeg of ``imageio-ffmpeg``).

    Raises
    ------
    inkwarp.errors.MissingFileError
        No such file.
    ValueError
        ffmpeg cannot decode it, or it has no frames (the message names the file).
    """
    name, fps, width, height, promised, rate = _probe(path)
    raw = _decode(name, "gray", promised=promised, size=width * height, rate=rate)
    count = len(raw) // (width * height)
    if count == 0:
        raise _no_frames(name)
    data = np.frombuffer(raw, np.uint8)[:count * width * height].reshape(count, height, width)
    return Video(name, fps, width, height, list(data))


def read_frame(path: str | os.PathLike[str], frame: int = 0) -> np.ndarray:
    """Frame ``frame`` of a video as RGB ``uint8`` ``(H, W, 3)`` (the picture to trace on).

    Raises
    ------
    ValueError
        The video cannot be decoded, or has no such frame (the message says how many it has).
    """
    if frame < 0:
        raise InputError(f"frame {frame}: frames are numbered from 0")
    name, _, width, height, promised, rate = _probe(path)
    size = width * height * 3
    raw = _decode(name, "rgb24", frames=frame + 1, promised=promised, size=size, rate=rate)
    if len(raw) < size * (frame + 1):
        count = len(_decode(name, "gray", promised=promised, size=width * height, rate=rate)) // (width * height)
        raise InputError(f"frame {frame}: {name} has frames 0 to {count - 1}; give a frame "
                         f"number below {count}")
    start = size * frame
    return np.frombuffer(raw, np.uint8)[start:start + size].reshape(height, width, 3).copy()


# ---- the drawing as tracked points -------------------------------------------------------

@dataclass
class _Feature:
    id: str
    kind: str
    closed: bool
    rest: np.ndarray                       # (N, 2) control points at frame K
    keys: dict[int, np.ndarray]            # frame -> (N, 2): corrections
    rows: slice = field(default_factory=lambda: slice(0, 0))  # this feature's rows in the tracked point array


def _curve_samples(f: _Feature, pose: np.ndarray) -> np.ndarray:
    """Points along the feature's curve for ``pose`` (the same parameters as at rest)."""
    from inkwarp.drawing import sample

    if f.kind == "point" or len(f.rest) < 2:
        return np.empty((0, 2))
    kind = "polyline" if f.kind in ("polyline", "cut", "region") else "spline"
    closed = f.closed or f.kind == "region"
    pts, moves = sample(kind, f.rest, pose, closed=closed, spacing=SAMPLE_SPACING_PX)
    return pts + moves


def _all_points(features: list[_Feature], poses: Sequence[np.ndarray]) -> np.ndarray:
    """Control points then curve samples of every feature, stacked."""
    blocks = []
    for f, pose in zip(features, poses):
        blocks.append(pose)
        blocks.append(_curve_samples(f, pose))
    return np.concatenate(blocks).astype(np.float64) if blocks else np.empty((0, 2))


def _layout(features: list[_Feature]) -> None:
    """Give each feature its rows (its control points, then its curve samples) in the
    stacked arrays of tracked positions."""
    start = 0
    for f in features:
        n = len(f.rest) + len(_curve_samples(f, f.rest))
        f.rows = slice(start, start + n)
        start += n


# ---- one track from an anchor -----------------------------------------------------------

class _Tracker:
    """Follows a set of points from an anchor frame through consecutive frames."""

    def __init__(self, frames: list[np.ndarray], options: TrackOptions) -> None:
        cv2 = _cv2()
        self.cv2 = cv2
        self.frames = frames
        self.options = options
        self.dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        self.lk = dict(winSize=(LK_WINDOW_PX, LK_WINDOW_PX), maxLevel=LK_LEVELS,
                       criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 0.005))
        self._eig: dict[int, np.ndarray] = {}

    def min_eig(self, k: int) -> np.ndarray:
        if k not in self._eig:
            grey = self.frames[k].astype(np.float32) / 255.0
            self._eig[k] = self.cv2.cornerMinEigenVal(grey, 7, ksize=3)
        return self._eig[k]

    def _lk(self, a: np.ndarray, b: np.ndarray, pts: np.ndarray, guess: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
        p0 = pts.astype(np.float32).reshape(-1, 1, 2)
        p1 = guess.astype(np.float32).reshape(-1, 1, 2).copy()
        out, status, _ = self.cv2.calcOpticalFlowPyrLK(
            a, b, p0, p1, flags=self.cv2.OPTFLOW_USE_INITIAL_FLOW, **self.lk)
        return out.reshape(-1, 2).astype(np.float64), status.reshape(-1).astype(bool)

    def _lk_checked(self, a: np.ndarray, b: np.ndarray, pts: np.ndarray, guess: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
        """LK from ``a`` to ``b`` and back: the positions in ``b`` and the forward-backward
        error (inf where LK failed)."""
        fwd, ok1 = self._lk(a, b, pts, guess)
        # Back from where the forward guess's move implies, not from the start itself: started
        # there, a track run off under a flat cover "came back" by construction.
        back, ok2 = self._lk(b, a, fwd, fwd - (guess - pts))
        fb = np.linalg.norm(back - pts, axis=1)
        fb[~(ok1 & ok2) | ~np.isfinite(fb)] = np.inf
        return fwd, fb

    def _mismatch(self, a: np.ndarray, at_a: np.ndarray, b: np.ndarray, at_b: np.ndarray,
                  side: int = LK_WINDOW_PX) -> np.ndarray:
        """The mean absolute difference of the windows (``side`` pixels square, by default
        Lucas-Kanade's) of ``a`` at ``at_a`` and of ``b`` at ``at_b``, point by point."""
        return np.array([float(np.abs(u - v).mean()) for u, v in self._window_pairs(a, at_a, b, at_b, side)])

    def _likeness(self, a: np.ndarray, at_a: np.ndarray, b: np.ndarray, at_b: np.ndarray) -> np.ndarray:
        """The correlation of the Lucas-Kanade windows of ``a`` at ``at_a`` and of ``b`` at
        ``at_b`` (each less its mean: a change of brightness does not count), point by point."""
        pairs = ((u - u.mean(), v - v.mean()) for u, v in self._window_pairs(a, at_a, b, at_b, LK_WINDOW_PX))
        return np.array([float((u * v).sum() / max(np.sqrt((u * u).sum() * (v * v).sum()), 1e-12)) for u, v in pairs])

    def _window_pairs(self, a: np.ndarray, at_a: np.ndarray, b: np.ndarray, at_b: np.ndarray, side: int) -> Iterator[Any]:
        """``side``-pixel square windows of ``a`` at ``at_a`` and of ``b`` at ``at_b``, point by point."""
        size, window = (side, side), self.cv2.getRectSubPix
        for p, q in zip(at_a, at_b):
            yield (window(a, size, tuple(map(float, p)), patchType=self.cv2.CV_32F),
                   window(b, size, tuple(map(float, q)), patchType=self.cv2.CV_32F))

    def predicted(self, template: np.ndarray, rest: np.ndarray, now: np.ndarray,
                  good: np.ndarray, box: tuple[int, int, int, int] | None = None) -> tuple[np.ndarray, Any, Any] | None:
        """The anchor frame warped by the thin plate taking ``rest[good]`` to ``now[good]``
        (evaluated every 8 px and interpolated), that map's inverse and the map itself, or
        None with too few points; only the pixels of ``box`` (``x0, y0, x1, y1``) where
        given."""
        from inkwarp.methods import ThinPlateMap

        idx = _spread(np.flatnonzero(good), rest)
        if len(idx) < 3:
            return None
        try:
            inverse, forward = ThinPlateMap(now[idx], rest[idx]), ThinPlateMap(rest[idx], now[idx])
        except ValueError:
            return None
        x0, y0, x1, y1 = box if box is not None else (0, 0, template.shape[1], template.shape[0])
        w, h, step = x1 - x0, y1 - y0, 8
        gx = np.append(np.arange(0, w - 1, step, dtype=np.float64), w - 1)
        gy = np.append(np.arange(0, h - 1, step, dtype=np.float64), h - 1)
        xx, yy = np.meshgrid(gx + x0, gy + y0)
        src = inverse(np.stack([xx.ravel(), yy.ravel()], axis=1)).reshape(len(gy), len(gx), 2)
        # Bilinear upsampling of the coarse map: cv2.resize with the corners aligned.
        full = np.empty((h, w, 2), np.float32)
        for c in range(2):
            full[..., c] = _upsample(src[..., c], gx, gy, w, h)
        picture = self.cv2.remap(template, full[..., 0], full[..., 1], self.cv2.INTER_CUBIC,
                                 borderMode=self.cv2.BORDER_REPLICATE)
        return picture, inverse, forward

    def run(self, anchor: int, start_points: np.ndarray, stop: int,
            tick: Callable[[], None], neighbours: np.ndarray | None = None,
            groups: np.ndarray | None = None) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
        """Track from frame ``anchor`` (points ``start_points``) to frame ``stop`` (either
        way). Returns, per frame, the positions and each point's forward-backward error.
        ``neighbours`` (see :func:`_neighbours`) lets the points of a curve vouch for each
        other (:func:`_odd_ones`); ``groups`` (each point's feature) warps the windows a
        feature's turned points are registered with by that feature's own thin plate."""
        positions = {anchor: start_points.copy()}
        errors = {anchor: np.zeros(len(start_points))}
        step = 1 if stop >= anchor else -1
        h, w = self.frames[anchor].shape
        template = self.frames[anchor]
        eig0 = _bilinear(self.min_eig(anchor)[..., None], start_points)[:, 0]
        textured_at_anchor = eig0 > TRUST_MIN_EIG
        # Points whose window reached past the picture's edge where traced (see `whole` below).
        near_edge = off_picture(start_points, w, h, -LK_WINDOW_PX / 2)
        current = start_points.copy()
        # Where each point was last confirmed: a lost point is looked for there again.
        last_seen = start_points.copy()
        lost = np.zeros(len(current), bool)
        for k in range(anchor + step, stop + step, step):
            a, b = self.frames[k - step], self.frames[k]
            flow = self.dis.calc(a, b, None)
            back_flow = self.dis.calc(b, a, None)
            dense = current + _bilinear(flow, current)
            dense_fb = np.linalg.norm(dense + _bilinear(back_flow, dense) - current, axis=1)
            local, local_fb = self._lk_checked(a, b, current, dense)
            estimate = np.where((local_fb < TRUST_FB_PX)[:, None], local, dense)
            # Texture where the point was traced and where it is now: a point that slid
            # onto flat skin passes any forward-backward check.
            textured = textured_at_anchor & (
                _bilinear(self.min_eig(k)[..., None], estimate)[:, 0] > TRUST_MIN_EIG)
            # Drift-free: the anchor's picture warped onto the estimate (the thin plate of
            # the points Lucas-Kanade follows), registered to this frame.
            good = textured & (local_fb < TRUST_FB_PX)
            # Where the anchor's picture is only shifted under a Lucas-Kanade window, it is
            # registered as it is (sharper); where it is turned or stretched, warped first.
            refined, refined_fb = self._lk_checked(template, b, start_points, estimate)
            warped = self.predicted(template, start_points, estimate, good)
            if warped is not None:
                picture, inverse, forward = warped
                half = LK_WINDOW_PX / 2
                here = inverse(estimate)
                bent = np.zeros(len(estimate))
                for axis in (np.array([half, 0.0]), np.array([0.0, half])):
                    bent = np.maximum(bent, np.linalg.norm(
                        inverse(estimate + axis) - here - axis, axis=1))
                turned = bent > 0.2
                if turned.any():
                    at_turned = estimate[turned]
                    # Registered from where the warped picture shows the point's anchor window
                    # (the plate's image of its rest place), not from the estimate: the plate
                    # interpolates only the points `_spread` keeps, and a point off them,
                    # registered from its estimate, was confirmed where its drift had taken it
                    # (the warped picture matches the frame everywhere the plate is right).
                    in_picture = forward(start_points[turned])
                    again, again_fb = self._lk_checked(picture, b, in_picture, at_turned)
                    misfit = self._mismatch(picture, in_picture, b, again)
                    # The whole drawing's plate bends between a thing that turns and a still point
                    # elsewhere, and a window warped by it is registered a few pixels off, passing
                    # every check: a feature that moves as one piece (its followed points span an
                    # area and fit one affine map within a pixel: a disk that turns, not lids that
                    # close) also tries its own plate, and each point keeps the warp whose window
                    # matches this frame better.
                    for group in (np.unique(groups[turned]) if groups is not None else []):
                        mine = good & (groups == group)
                        # (Not where it holds every good point: its plate is the drawing's.)
                        if (mine == good).all() or not (_spans_area(start_points[mine]) and _affine_misfit(start_points[mine], estimate[mine]) <= 1.0):
                            continue
                        at = np.flatnonzero(groups[turned] == group)
                        # Warped only about the feature's turned points (as far as Lucas-Kanade looks).
                        pad = 3 * LK_WINDOW_PX * 2 ** LK_LEVELS
                        lo = np.maximum(np.floor(at_turned[at].min(axis=0)) - pad, 0).astype(int)
                        hi = np.minimum(np.ceil(at_turned[at].max(axis=0)) + pad + 1, [w, h]).astype(int)
                        own = self.predicted(template, start_points, estimate, mine, (*lo, *hi))
                        if own is None:
                            continue
                        in_own = own[2](start_points[turned][at]) - lo
                        found, found_fb = self._lk_checked(own[0], b[lo[1]:hi[1], lo[0]:hi[0]], in_own, at_turned[at] - lo)
                        found = found + lo
                        fits = self._mismatch(own[0], in_own, b, found)
                        better = (found_fb < TRUST_FB_PX) & (fits < misfit[at])
                        again[at[better]], again_fb[at[better]], misfit[at[better]] = found[better], found_fb[better], fits[better]
                    # A warped picture is the thin plate's guess of how the window turned: kept
                    # unless the anchor's picture as it is matches this frame better (a still
                    # point beside an object that moves away is bent by the plate, not in the
                    # picture).
                    plain = (refined_fb[turned] < TRUST_FB_PX) & (
                        self._mismatch(template, start_points[turned], b, refined[turned]) <= misfit)
                    take = np.flatnonzero(turned)[~plain]
                    refined[take], refined_fb[take] = again[~plain], again_fb[~plain]
            use_anchor = (refined_fb < TRUST_FB_PX) & (np.linalg.norm(refined - estimate, axis=1) < REGAIN_PX)
            # A lost point (covered, or out of the picture) may show again where it was
            # last seen, far from where the frame-to-frame estimate has taken it.
            retry = np.flatnonzero(lost & ~use_anchor)
            regained = np.zeros(len(current), bool)
            if len(retry):
                again, again_fb = self._lk_checked(template, b, start_points[retry], last_seen[retry])
                found = (again_fb < TRUST_FB_PX) & (np.linalg.norm(again - last_seen[retry], axis=1) < REGAIN_PX)
                refined[retry[found]], refined_fb[retry[found]] = again[found], again_fb[found]
                use_anchor[retry[found]] = regained[retry[found]] = True
            best = np.where(use_anchor[:, None], refined, estimate)
            # Texture at the anchor and where the point is placed now (a point covered by
            # a flat box, or slid onto flat skin, passes any forward-backward check).
            textured_now = textured_at_anchor & (
                _bilinear(self.min_eig(k)[..., None], best)[:, 0] > TRUST_MIN_EIG)
            inside = ~off_picture(best, w, h, 0.0)
            # (the texture at the estimate, or where a lost point was found again)
            trusted = np.where(regained, textured_now, textured) & ((local_fb < TRUST_FB_PX) | use_anchor) & inside
            # A point its curve's neighbours on both sides disagree with, where they agree with
            # each other, is not trusted, however well its checks pass: its window straddles
            # the edge of what moves and holds to what stays (a region's corner traced just
            # inside a square sliding over a still background kept to the background).
            odd, vouched = _odd_ones(best - current, neighbours, trusted, self.options.lost_px)
            if odd.any():
                # Which of the two is right, the point or its neighbours, the picture close around
                # it says (a still point beside an object that moves away is the one that stays):
                # the anchor's few pixels around it match the frame better where it is, or where
                # its neighbours' move would take it.
                at = np.flatnonzero(odd)
                own = self._mismatch(template, start_points[at], b, best[at], ODD_WINDOW_PX)
                moved_with = self._mismatch(template, start_points[at], b, current[at] + vouched[at], ODD_WINDOW_PX)
                odd[at[own <= moved_with]] = False
            # A stretch of a curve that jumped, as one, a period of a repeating texture off (every
            # check passes there, the anchor's too) is no odd one to its neighbours: its feature's
            # move as a whole says so.
            trusted &= ~odd & ~_off_its_feature(groups, trusted, current, best - current, JUMP_PX)
            untrusted = ~trusted
            if untrusted.any() and trusted.sum() >= 3:
                fill = _thin_plate_fill(start_points, best, trusted, untrusted)
                if warped is not None:
                    # What the thin plate misses, dense flow from the anchor's picture warped
                    # by it sees (faint gradients): a correction that does not accumulate.
                    # Only small ones: a large one is the picture changing (a lid closing
                    # over an eye), not the thin plate's error.
                    residual = _bilinear(self.dis.calc(warped[0], b, None), fill)
                    small = np.linalg.norm(residual, axis=1) < RESIDUAL_PX
                    fill[small] += residual[small]
                best[untrusted] = fill
            else:
                best[odd] = current[odd] + vouched[odd]
            vouch_error = np.linalg.norm(best - current - vouched, axis=1)
            current = best
            positions[k] = best.copy()
            self._eig.pop(k - step, None)
            # Lost: a point textured where it was traced that is not confirmed here: out of
            # the picture, on no texture, or by neither Lucas-Kanade check (an untextured
            # one is placed by the thin plate; only the dense flow's own check speaks for
            # it). Once lost, a point stays lost until it is registered to the anchor again
            # (noise can pass a frame-to-frame check by chance).
            lost_px = self.options.lost_px
            checked = np.where(lost, refined_fb, np.minimum(local_fb, refined_fb))
            # A registration to the anchor that holds (its own check passes) but lands
            # elsewhere says the point has drifted: frame-to-frame checks cannot see drift
            # (a point stuck beside its feature on a still picture passes them every frame).
            apart = np.linalg.norm(refined - best, axis=1)
            drifted = (refined_fb <= lost_px) & (apart > lost_px)
            checked = np.where(drifted, np.maximum(checked, apart), checked)
            # A point the thin plate placed was checked where Lucas-Kanade put it: the checks
            # speak for the plate's place only as far as it lies from theirs.
            moved = np.minimum(np.linalg.norm(best - local, axis=1), np.linalg.norm(best - refined, axis=1))
            checked = np.where(untrusted, np.maximum(checked, moved), checked)
            # A lost point is confirmed again only by a registration to the anchor that Lucas-
            # Kanade trusts, with its whole window on the picture: one leaving it matches what
            # is left of its texture at the edge (border pixels repeated), or an edge beside
            # it, well enough to pass the looser checks, far from where it went.
            whole = ~off_picture(best, w, h, -LK_WINDOW_PX / 2) | near_edge
            again = (use_anchor | regained) & whole
            # An odd point is placed by its neighbours, so its place is checked by theirs: how far it
            # lies from their move, and no better than the worst of their own checks.
            if odd.any():
                take = (neighbours[odd] >= 0) & trusted[neighbours[odd]]
                theirs = np.where(take, checked[neighbours[odd]], 0.0).max(axis=1)
                checked[odd] = np.maximum(vouch_error[odd], theirs)
            confirmed = (textured_now | odd) & inside & (checked <= lost_px) & (~lost | again | odd)
            # Found again only where it looks as it did: a window of another texture (the
            # background where an object left) passes Lucas-Kanade's checks, correlated with
            # the anchor's as two textures are (below 0.45; the same window 10° turned, 0.7).
            back = np.flatnonzero(confirmed & lost)
            if len(back):
                confirmed[back[self._likeness(template, start_points[back], b, best[back]) < REGAIN_LIKENESS]] = False
            lost = textured_at_anchor & ~confirmed
            last_seen[confirmed] = best[confirmed]
            # Any point placed more than `lost_px` off the picture is lost too: nothing there
            # confirms it (an untextured one follows the thin plate of the others, which can
            # carry it out of the frame over a background that stays).
            off = off_picture(best, w, h, lost_px)
            # A lost point's error is what its check found (a drift, a failed check), or
            # infinite where nothing could be checked (no texture, off the picture).
            unseen = off | (lost & (checked <= lost_px))
            errors[k] = np.where(unseen, np.inf, np.where(textured_at_anchor, checked, dense_fb))
            tick()
        return positions, errors


def _spans_area(points: np.ndarray) -> bool:
    """Whether points (three at least) spread over an area: their spread across their main
    line at least a quarter of that along it, and at least half a Lucas-Kanade window."""
    if len(points) < 3:
        return False
    along, across = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)[:2] / np.sqrt(len(points))
    return bool(across >= 0.25 * along and across >= LK_WINDOW_PX / 4)


def _affine_misfit(rest: np.ndarray, now: np.ndarray) -> float:
    """How far the best affine map taking ``rest`` to ``now`` leaves the points (least
    squares; the median distance, which a stray point does not sway)."""
    a = np.column_stack([rest, np.ones(len(rest))])
    fit, *_ = np.linalg.lstsq(a, now, rcond=None)
    return float(np.median(np.linalg.norm(a @ fit - now, axis=1)))


def _neighbours(features: list[_Feature], points: np.ndarray) -> np.ndarray:
    """For each of the stacked ``points``, the points of its own feature's curve within 2.5
    sample spacings of it and not at its place, as rows of indices padded with -1: for a
    curve sample the two samples each way along the curve (two on one side at an open
    end), for a control point the samples near it."""
    reach = 2.5 * SAMPLE_SPACING_PX
    blocks: list[tuple[np.ndarray, np.ndarray]] = []  # (rows, their neighbours, -1 padded)
    for f in features:
        rows = np.arange(len(points))[f.rows]
        control, samples = rows[:len(f.rest)], rows[len(f.rest):]
        if len(samples) == 0:
            continue
        d = np.linalg.norm(points[control, None] - points[None, samples], axis=2)
        near = (d > 0.5) & (d <= reach)
        width = max(int(near.sum(axis=1).max(initial=0)), 1)
        order = np.argsort(~near, axis=1, kind="stable")[:, :width]  # the near ones first
        blocks.append((control, np.where(np.take_along_axis(near, order, 1), samples[order], -1)))
        k = np.arange(len(samples))[:, None] + [-2, -1, 1, 2]
        if f.closed or f.kind == "region":
            k %= len(samples)
        inside = (k >= 0) & (k < len(samples))
        other = samples[np.clip(k, 0, len(samples) - 1)]
        d = np.linalg.norm(points[other] - points[samples][:, None], axis=2)
        blocks.append((samples, np.where(inside & (d > 0.5) & (d <= reach), other, -1)))
    out = np.full((len(points), max([b.shape[1] for _, b in blocks], default=0)), -1)
    for rows, block in blocks:
        out[rows, :block.shape[1]] = block
    return out


def _odd_ones(motion: np.ndarray, neighbours: np.ndarray | None, trusted: np.ndarray,
              lost_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The points whose motion from the last frame is more than ``lost_px`` from the mean
    motion of their trusted ``neighbours`` (two at least) while those agree within half of
    it, and that mean motion (zero where there is none)."""
    odd, vouched = np.zeros(len(motion), bool), np.zeros_like(motion)
    if neighbours is None or neighbours.shape[1] < 2:
        return odd, vouched
    take = (neighbours >= 0) & trusted[neighbours]
    count = take.sum(axis=1)
    around = np.where(take[..., None], motion[neighbours], 0.0)
    vouched = around.sum(axis=1) / np.maximum(count, 1)[:, None]
    spread = np.where(take, np.linalg.norm(around - vouched[:, None], axis=2), 0.0).max(axis=1)
    odd = (count >= 2) & (spread <= lost_px / 2) & (np.linalg.norm(motion - vouched, axis=1) > lost_px)
    return odd, vouched


def _off_its_feature(groups: np.ndarray | None, trusted: np.ndarray, at: np.ndarray, motion: np.ndarray,
                     limit: float) -> np.ndarray:
    """The trusted points whose ``motion`` from ``at`` lies more than ``limit`` from their
    feature's, where the rest of it moves as one piece: the affine map fitted to the moves of
    its trusted points (four at least) within ``limit`` of their median move, and then within
    ``limit`` of that map, leaves those within a pixel (not a lid that closes, which bends)."""
    off = np.zeros(len(motion), bool)
    for group in (np.unique(groups[trusted]) if groups is not None else []):
        mine = np.flatnonzero(trusted & (groups == group))
        if len(mine) < 4:
            continue
        a, move = np.column_stack([at[mine], np.ones(len(mine))]), motion[mine]
        near = np.linalg.norm(move - np.median(move, axis=0), axis=1) <= limit
        for _ in range(2):
            if near.sum() < 4:
                break
            fit, *_ = np.linalg.lstsq(a[near], move[near], rcond=None)
            left = np.linalg.norm(a @ fit - move, axis=1)
            near = left <= limit
        else:
            if near.any() and left[near].max() <= 1.0:
                off[mine[~near]] = True
    return off


def _thin_plate_fill(rest: np.ndarray, now: np.ndarray, trusted: np.ndarray,
                     untrusted: np.ndarray) -> np.ndarray:
    """Where the untrusted points go under the thin plate fitted to the trusted ones."""
    from inkwarp.methods import ThinPlateMap

    idx = _spread(np.flatnonzero(trusted), rest)
    try:
        w = ThinPlateMap(rest[idx], now[idx])
    except ValueError:
        return now[untrusted]
    return w(rest[untrusted])


def _spread(idx: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """At most :data:`TPS_POINTS` of the points ``idx``, one per :data:`TPS_CELL_PX` cell
    (close centres with noisy targets make the thin plate swing far from them)."""
    _, first = np.unique(np.floor(rest[idx] / TPS_CELL_PX), axis=0, return_index=True)
    idx = idx[np.sort(first)]
    if len(idx) > TPS_POINTS:
        idx = idx[np.linspace(0, len(idx) - 1, TPS_POINTS).round().astype(int)]
    return idx


def _upsample(coarse: np.ndarray, gx: np.ndarray, gy: np.ndarray, w: int, h: int) -> np.ndarray:
    """Values on the grid ``gx`` x ``gy`` interpolated bilinearly at every pixel."""
    ix = np.interp(np.arange(w), gx, np.arange(len(gx)))
    iy = np.interp(np.arange(h), gy, np.arange(len(gy)))
    x0 = np.minimum(ix.astype(int), len(gx) - 2) if len(gx) > 1 else np.zeros(w, int)
    y0 = np.minimum(iy.astype(int), len(gy) - 2) if len(gy) > 1 else np.zeros(h, int)
    fx, fy = (ix - x0)[None, :], (iy - y0)[:, None]
    x1, y1 = np.minimum(x0 + 1, len(gx) - 1), np.minimum(y0 + 1, len(gy) - 1)
    top = coarse[y0][:, x0] * (1 - fx) + coarse[y0][:, x1] * fx
    bottom = coarse[y1][:, x0] * (1 - fx) + coarse[y1][:, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def _bilinear(img: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """``img`` (H, W, C) at real positions ``pts`` (N, 2), clamped to the edges."""
    h, w = img.shape[:2]
    x = np.clip(pts[:, 0], 0, w - 1)
    y = np.clip(pts[:, 1], 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(int), w - 2) if w > 1 else np.zeros(len(x), int)
    y0 = np.minimum(np.floor(y).astype(int), h - 2) if h > 1 else np.zeros(len(y), int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    return ((img[y0, x0] * (1 - fx) + img[y0, x1] * fx) * (1 - fy)
            + (img[y1, x0] * (1 - fx) + img[y1, x1] * fx) * fy).astype(np.float64)


# ---- the whole track ---------------------------------------------------------------------

@dataclass
class TrackOptions:
    """Settings of :func:`track_dict`."""

    #: A feature is lost at a frame where its points' median forward-backward error is over this.
    lost_px: float = 2.0


def _features(doc: dict[str, Any], fps: float, count: int, frame: int, where: str,
              size: tuple[int, int]) -> list[_Feature]:
    out, (w, h) = [], size
    for i, f in enumerate(doc.get("features") or []):
        rest = np.asarray(f["rest"], dtype=np.float64).reshape(-1, 2)
        keys: dict[int, np.ndarray] = {}
        for j, key in enumerate(f.get("keys") or []):
            k = int(round(float(key["t"]) * fps))
            # Within the last frame's span, or at its end (the scene's duration, where a
            # scene's last keys often are): the last frame.
            if k == count and float(key["t"]) * fps <= count * (1 + 1e-6):
                k = count - 1
            if not 0 <= k < count:
                raise InputError(
                    f"{where}: features[{i}].keys[{j}]: t = {key['t']} s is frame {k}, outside "
                    f"the video's frames 0 to {count - 1}; remove the key or move it inside")
            points = np.asarray(key["points"], dtype=np.float64).reshape(-1, 2)
            if k == frame:  # the rest drawing is the anchor at frame K
                off = float(np.abs(points - rest).max()) if points.shape == rest.shape else math.inf
                if off > 0.01:
                    warnings.warn(f"{where}: features[{i}] ({f['id']}): its key at t = {key['t']} s is "
                                  f"frame {k}, the frame the drawing is traced on, where its rest is the "
                                  f"anchor; the key ({off:.3g} px from the rest) is replaced by the track. "
                                  "Trace on another frame with --frame, or move the key off it",
                                  InkwarpWarning, stacklevel=caller_outside())
                continue
            # A correction far off the picture (a typed coordinate gone wrong) is tracked from
            # where nothing can be seen, and the lost track's warning would point back at it.
            if f.get("kind") != "cut" and off_picture(points, w, h, max(w, h)).any():
                far = float(np.max(np.maximum(-points, points - [w - 1, h - 1])))
                warnings.warn(f"{where}: features[{i}] ({f['id']}): its key at t = {key['t']} s (frame {k}) "
                              f"has a point {far:.0f} px off the {w}x{h} picture, where the tracker sees "
                              "nothing to follow; check the key's points", InkwarpWarning, stacklevel=caller_outside())
            keys[k] = points
        out.append(_Feature(str(f["id"]), str(f["kind"]), bool(f.get("closed", False)), rest, keys))
    return out


def _range_of(anchor: int, anchors: Sequence[int], count: int) -> tuple[int, int]:
    """Frames a feature's anchor influences: up to its neighbouring anchors (or the ends)."""
    i = list(anchors).index(anchor)
    lo = anchors[i - 1] if i > 0 else 0
    hi = anchors[i + 1] if i + 1 < len(anchors) else count - 1
    return lo, hi


#: A gap of at most this many frames between two frames where a feature is lost (no anchor
#: in it) counts as lost too: a check that passes at a few frames between lost ones does not
#: vouch for it (a track left on the wrong texture passed at single frames 28-39 px off).
REFOUND_FRAMES = 5


def _stray_after(lost: Sequence[int], series: np.ndarray, errors: Sequence[np.ndarray | None],
                 seen: np.ndarray, anchors: Container[int], lost_px: float) -> list[int]:
    """The ``lost`` frames (ascending) of a feature with the frames on either side of each
    run where it is still lost in part: a control point on the picture not yet confirmed
    again lies more than ``lost_px`` from where the feature's confirmed points carry it from
    the frame beside the run (a point under a cover, placed meanwhile by the plate of what
    moved past, stays there a frame after the cover goes while its neighbours are found)."""
    count, n, out = len(series), series.shape[1], set(lost)
    for step in (1, -1):
        for k in sorted(out, reverse=step < 0):
            if k + step in out or k + step in anchors or not 0 <= k + step < count:
                continue
            start = next((j for j in range(k, -1 if step > 0 else count, -step) if j not in out), None)
            j = k + step
            while start is not None and 0 <= j < count and j not in anchors and errors[j] is not None:
                err = errors[j][:n]
                confirmed, unseen = seen & (err <= lost_px), seen & ~np.isfinite(err)
                if not (confirmed.any() and unseen.any()):
                    break
                move = (series[j][confirmed] - series[start][confirmed]).mean(axis=0)
                if np.linalg.norm(series[j][unseen] - series[start][unseen] - move, axis=1).max() <= lost_px:
                    break
                out.add(j)
                j += step
    return sorted(out)


def _kept_in_shape(series: np.ndarray, errors: Sequence[np.ndarray | None], lost: Sequence[int],
                   anchors: Container[int], lost_px: float) -> None:
    """A feature's control points in ``series`` at its ``lost`` frames (not its anchors): the
    shape it has at the frames just before and after each run of them, blended linearly in
    time, moved as a whole by the mean move of the points whose checks passed there where
    they are at least half of them (else left as blended). A run that starts or ends the
    clip holds the shape of its one side, moved by the points that passed, or where none
    did by all its points as placed (the drawing's thin plate). Where the checks fail, the
    points as tracked can fold and cross (a lip pulled over the jaw of a mouth that opens);
    kept in shape, the keys stay a drawing to correct."""
    count, n = len(series), series.shape[1]
    for run in _runs(k for k in lost if k not in anchors):
        a, b = run[0] - 1, run[-1] + 1
        if a < 0 and b >= count:
            continue
        for k in run:
            s = 0.0 if b >= count else 1.0 if a < 0 else (k - a) / (b - a)
            shape = (1 - s) * series[max(a, 0)] + s * series[min(b, count - 1)]
            err = errors[k]
            passed = np.zeros(n, bool) if err is None else err[:n] <= lost_px
            if 0 <= a and b < count:
                # Between two places it was confirmed at, the blend holds unless most points say otherwise.
                passed &= passed.sum() * 2 >= n
            elif not passed.any():
                # Past the last confirmed frame (or before the first): moved as the rest of the drawing places it.
                passed[:] = True
            series[k] = shape + (series[k][passed] - shape[passed]).mean(axis=0) if passed.any() else shape


def _held_lost(frames: Sequence[int], anchors: Container[int]) -> list[int]:
    """The lost ``frames`` (ascending) with the gaps of at most :data:`REFOUND_FRAMES`
    between them filled, where no anchor lies in the gap."""
    out: list[int] = []
    for k in frames:
        if out and k - out[-1] - 1 <= REFOUND_FRAMES and not any(a in anchors for a in range(out[-1] + 1, k)):
            out.extend(range(out[-1] + 1, k))
        out.append(k)
    return out


def _runs(frames: Iterable[int]) -> list[list[int]]:
    """The ascending ``frames`` in runs of consecutive ones."""
    runs: list[list[int]] = []
    for k in frames:
        if runs and runs[-1][-1] == k - 1:
            runs[-1].append(k)
        else:
            runs.append([k])
    return runs


def _frames_text(frames: Sequence[int]) -> str:
    return ", ".join(f"{r[0]}" if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in _runs(frames))


def as_option(err: ValueError, frame: int) -> ValueError:
    """``err`` with the command line's option for a ``frame N: ...`` message (``--frame N:
    ...``), as the commands name their options; any other message as it is."""
    text = str(err)
    return ValueError("--" + text) if text.startswith(f"frame {frame}:") else err


def track_dict(video: str | os.PathLike[str] | Video, scene: Any, frame: int = 0, *,
               simplify_px: float | None = None, lost_px: float = 2.0,
               progress: Callable[[int], Any] | None = None,
               relative_to: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The scene document with its drawing tracked through the video.

    Parameters
    ----------
    video : path or Video
        The footage (anything ffmpeg decodes).
    scene : path, dict or inkwarp.Scene
        Its features' ``rest`` geometry is traced over frame ``frame`` of the video; its
        size must be the video's. Keys it has at other frames are corrections the track
        passes through.
    frame : int
        The frame the drawing is traced on (``K``).
    simplify_px : float, optional
        Thin each feature's keys where linear interpolation between the kept ones stays
        within this many pixels of every dropped key (corrections are always kept).
    lost_px : float
        The forward–backward error (pixels, median over a feature's points) over which a
        feature counts as lost at a frame; lost features are named in an
        :class:`~inkwarp.InkwarpWarning`.
    progress : callable, optional
        Called with the total number of frame steps, it returns a callable called once
        per step (a progress bar).
    relative_to : path, optional
        The folder the result will be saved in: its relative image paths are rewritten
        for it (default: made absolute). A scene given as a dict keeps its paths.

    Returns
    -------
    dict
        The scene with ``fps`` and ``duration`` of the video and, for every feature, a
        ``linear`` key at every video frame ``k`` (``t = k / fps``) or, with
        ``simplify_px``, at the frames kept.
    """
    from inkwarp.transfer import _load, _rebase_images

    if not isinstance(video, (str, os.PathLike, Video)):
        raise InputError(f"the video must be a path or an inkwarp.track.Video; got {type(video).__name__}")
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise InputError(f"frame must be a whole number (the frame the drawing is traced on); got {frame!r:.40}")
    frame = int(frame)
    if progress is not None and not callable(progress):
        raise InputError(f"progress must be a function of the number of steps that returns one to call each step "
                         f"(or None); got {type(progress).__name__} {progress!r:.40}")
    from inkwarp.scene import _path_argument

    # (Checked here, not after the track: a wrong one is said before minutes of work.)
    rebased = Path(_path_argument(relative_to, "relative_to")).resolve() if relative_to is not None else None
    where = os.fspath(scene) if isinstance(scene, (str, os.PathLike)) else "the scene"
    loaded = None
    if isinstance(scene, (str, os.PathLike)):
        from inkwarp.cli._common import load_scene

        loaded = load_scene(os.fspath(scene))  # every problem of the file, with its JSON path
    doc, base = _load(scene, "input")
    clip = video if isinstance(video, Video) else read_video(video)
    count = len(clip)
    if count < 2:
        raise InputError(f"{clip.path}: has one frame (a still picture?); track follows the drawing "
                         "through a video's frames: give a video (any format ffmpeg reads)")
    size = (doc.get("width"), doc.get("height"))
    if None in size:  # the size of its images
        from inkwarp.scene import Scene

        loaded = loaded or (scene if isinstance(scene, Scene) else Scene.from_dict(doc, base_dir=base))
        size = (loaded.width, loaded.height)
    # An MP4 of an odd-sized scene (inkwarp's own) carries one more column or row, the edge
    # repeated: H.264 wants even sides. Its pixels are the scene's where they overlap.
    if size != (clip.width, clip.height) and tuple(v + v % 2 for v in size) != (clip.width, clip.height):
        raise InputError(
            f"{where}: the scene is {size[0]}x{size[1]} but the video {clip.path} is "
            f"{clip.width}x{clip.height}; trace the drawing on a frame of this video "
            f"(inkwarp frame {clip.path} -o frame.png) in a scene of its size")
    if not 0 <= frame < count:
        raise InputError(f"frame {frame}: {clip.path} has frames 0 to {count - 1} (numbered from 0); give "
                         f"a frame number from 0 to {count - 1}")
    if simplify_px is not None and not (math.isfinite(simplify_px) and simplify_px >= 0):
        raise InputError(f"simplify_px {simplify_px}: give a distance in pixels, 0 or more")
    if not (math.isfinite(lost_px) and lost_px > 0):
        raise InputError(f"lost_px {lost_px}: give a distance in pixels above 0")
    # A cut moves nothing (it tears the picture along its rest line): it is not tracked, and
    # keeps no keys.
    tracked = [(i, f) for i, f in enumerate(_features(doc, clip.fps, count, frame, where, (clip.width, clip.height))) if f.kind != "cut"]
    features = [f for _, f in tracked]
    if not features:
        cuts = " (cuts are not tracked: they tear the picture along their rest line)" if doc["features"] else ""
        raise InputError(f"{where}: has no features to track{cuts}; trace points or curves over frame {frame} "
                         f"of {clip.path} first (inkwarp frame {clip.path} --frame {frame} -o frame.png; "
                         "inkwarp new frame.png -o scene.json; inkwarp edit scene.json)")
    _layout(features)

    tracker = _Tracker(clip.frames, TrackOptions(lost_px))
    anchors_of = {f.id: sorted({frame, *f.keys}) for f in features}
    # A correction on no texture (a point put where it belongs while a flat box covers it):
    # nothing there for the tracker to follow. The key holds still around its frame,
    # unchecked, and the feature's other anchors track on past it (reaching the frames
    # where the feature shows again).
    # (A feature on no texture where traced is followed by the points around it everywhere: its
    # corrections are what moves it, and are kept as any correction is.)
    flat = {f.id for f in features if _untextured(tracker, frame, f, f.rest)}  # where traced
    blind_at = {f.id: {a for a, pose in f.keys.items() if a != frame and _untextured(tracker, a, f, pose)}
                if f.id not in flat else set() for f in features}
    union = sorted({k for a in anchors_of.values() for k in a})
    ranges: dict[int, tuple[int, int]] = {}
    for f in features:
        seeing = [a for a in anchors_of[f.id] if a not in blind_at[f.id]]
        for a in anchors_of[f.id]:
            lo, hi = _range_of(a, anchors_of[f.id] if a in blind_at[f.id] else seeing, count)
            old = ranges.get(a, (lo, hi))
            ranges[a] = (min(old[0], lo), max(old[1], hi))
    # The frames tracked from each anchor, the anchor's own included (a 60-frame clip traced
    # at one frame counts 60, not its 59 steps).
    steps = sum(hi - lo + 1 for lo, hi in ranges.values())
    tick = progress(steps) if progress is not None else (lambda: None)
    tick = tick or (lambda: None)

    tracks: dict[int, tuple[dict[int, np.ndarray], dict[int, np.ndarray]]] = {}
    groups = np.concatenate([np.full(f.rows.stop - f.rows.start, j) for j, f in enumerate(features)])  # each point's feature
    at_k = np.empty((0, 2))  # every feature's points where traced (none: only cuts)
    # Frame K first: the anchors at corrections start features without a key there
    # from its track.
    for a in sorted(union, key=lambda a: (a != frame, abs(a - frame))):
        poses = []
        for f in features:
            if a == frame:
                poses.append(f.rest)
            elif a in f.keys:
                poses.append(f.keys[a])
            else:
                poses.append(_blend(tracks, anchors_of[f.id], f, a, lost_px, blind_at[f.id])[0])
        start = _all_points(features, poses)
        if a == frame:
            at_k = start
        lo, hi = ranges[a]
        tick()
        near = _neighbours(features, start)
        fwd_pos, fwd_err = tracker.run(a, start, hi, tick, near, groups)
        back_pos, back_err = tracker.run(a, start, lo, tick, near, groups)
        tracks[a] = ({**back_pos, **fwd_pos}, {**back_err, **fwd_err})
        for f in features:
            if a in blind_at[f.id]:
                for k, pos in tracks[a][0].items():
                    if k != a:
                        pos[f.rows], tracks[a][1][k][f.rows] = start[f.rows], np.inf

    # Features on no texture where traced (flat skin, a plain background): the tracker cannot
    # see them move, and they follow the thin plate of the points around them.
    # Features wholly off the picture where traced (a correspondence point for transfer,
    # say): nothing there to see; they too follow the points around.
    # A feature partly off the picture where traced (a shoulder running out of the frame):
    # its points there are unseen in the same way, named so, and only its points on the
    # picture are judged for texture and for a lost track.
    beside = off_picture(at_k, clip.width, clip.height, 0.5)
    outside = {f.id for f in features if beside[f.rows].all()}
    partly = {f.id: int(beside[f.rows][:len(f.rest)].sum()) for f in features
              if f.id not in outside and beside[f.rows].any()}
    blind = [f.id for f in features if f.id not in outside and f.id in flat]
    lost: dict[str, list[int]] = {}
    for i, f in tracked:  # doc["features"][i] gets the keys
        series = np.empty((count, len(f.rest), 2))
        errors: list[np.ndarray | None] = []
        seen = ~beside[f.rows]
        for k in range(count):
            series[k], err = _blend(tracks, anchors_of[f.id], f, k, lost_px, blind_at[f.id])
            errors.append(err)
            if err is None or f.id in outside:
                continue
            # Lost where most of its points are, or where a point its keys are made of was
            # checked and found off (not merely unseen: a corner on the picture's edge), or is
            # placed more than `lost_px` off the picture (a still corner the others carry out).
            keys = err[:len(f.rest)][seen[:len(f.rest)]]
            carried = off_picture(series[k], clip.width, clip.height, lost_px)[seen[:len(f.rest)]]
            keys_off = bool(np.any(np.isfinite(keys) & (keys > lost_px)) or carried.any())
            if np.median(err[seen]) > lost_px or keys_off:
                lost.setdefault(f.id, []).append(k)
        if f.id in lost:
            anchors = set(anchors_of[f.id])
            stray = _stray_after(lost[f.id], series, errors, seen[:len(f.rest)], anchors, lost_px)
            lost[f.id] = _held_lost(stray, anchors)
            _kept_in_shape(series, errors, lost[f.id], anchors, lost_px)
        kept = range(count)
        if simplify_px is not None:
            kept = simplify_keys(series, simplify_px, keep=anchors_of[f.id])
        feature = doc["features"][i]
        # The traced frame and the corrections keep their points exactly as given (frame K
        # is then the picture as it is); the tracked ones are written to a thousandth.
        given = {frame: f.rest, **f.keys}
        feature["keys"] = [{"t": k / clip.fps,
                            "points": [[float(x), float(y)] if k in given else [round(float(x), 3), round(float(y), 3)]
                                       for x, y in (given[k] if k in given else series[k])],
                            "interpolation": "linear"} for k in kept]
    doc["fps"] = clip.fps if clip.fps != int(clip.fps) else int(clip.fps)
    doc["duration"] = count / clip.fps
    if lost:
        names = "; ".join(f"'{fid}' at frame{'s' if len(ks) > 1 else ''} {_frames_text(ks)}" for fid, ks in lost.items())
        warnings.warn(f"{clip.path}: lost track (checks over {lost_px:g} px) of "
                      f"{names}; check those frames and add a correction key there",
                      InkwarpWarning, stacklevel=caller_outside())
    if outside:
        names = ", ".join(f"'{f.id}'" for f in features if f.id in outside)
        warnings.warn(f"{clip.path}: {names} lie{'s' if len(outside) == 1 else ''} off the picture at frame {frame}, "
                      "where the tracker cannot see: followed by the tracked points around, not by the picture; "
                      "check them, and add a correction key where they stray",
                      InkwarpWarning, stacklevel=caller_outside())
    if partly:
        names = ", ".join(f"'{f.id}' ({partly[f.id]} of its {len(f.rest)} control points)" if partly[f.id]
                          else f"'{f.id}' (a part of its curve)" for f in features if f.id in partly)
        warnings.warn(f"{clip.path}: {names} lie{'s' if len(partly) == 1 else ''} partly off the picture at frame {frame}: "
                      "the points there are followed by the tracked points around, not by the picture; "
                      "check them, and add a correction key where they stray",
                      InkwarpWarning, stacklevel=caller_outside())
    if blind:
        names = ", ".join(f"'{fid}'" for fid in blind)
        warnings.warn(f"{clip.path}: {names} lie{'s' if len(blind) == 1 else ''} on no texture at frame {frame} "
                      "(a flat area the tracker cannot see move): followed by the tracked points around, "
                      "not by the picture; check them, and add a correction key where they stray",
                      InkwarpWarning, stacklevel=caller_outside())
    _rebase_images(doc, base, rebased)
    return doc


def _untextured(tracker: _Tracker, k: int, f: _Feature, pose: np.ndarray) -> bool:
    """Whether most of feature ``f``'s points in ``pose`` on frame ``k``'s picture lie on no
    texture (a flat area the tracker cannot see move)."""
    points = _all_points([f], [pose])
    h, w = tracker.frames[k].shape
    on = ~off_picture(points, w, h, 0.5)
    eig = _bilinear(tracker.min_eig(k)[..., None], points)[:, 0]
    return bool(on.any() and np.mean(eig[on] <= TRUST_MIN_EIG) > 0.5)


def _blend(tracks: dict, anchors: Sequence[int], f: _Feature, k: int, lost_px: float,
           blind: Container[int] = ()) -> tuple[np.ndarray, np.ndarray | None]:
    """Feature ``f``'s control points at frame ``k``: its anchors' tracks blended linearly
    between the anchors around ``k`` (where one of the two has lost the feature at ``k``
    and the other has not, the other's alone; where both have, the track of the nearest
    anchor not ``blind`` on either side that holds there, alone); and its points' errors,
    each track's checks blended with the same weights (a blend of two places is off by at
    most the blend of their errors: a track that strays near the far anchor hardly moves
    the points there)."""
    n = len(f.rest)

    def around(usable: Sequence[int]) -> list[tuple[float, int]]:
        before = [a for a in usable if a <= k and a in tracks and k in tracks[a][0]]
        after = [a for a in usable if a >= k and a in tracks and k in tracks[a][0]]
        if before and after:
            a, b = before[-1], after[0]
            return [(1.0, a)] if a == b else [((b - k) / (b - a), a), ((k - a) / (b - a), b)]
        return [(1.0, (before or after)[-1 if before else 0])] if before or after else []

    def holds(a: int) -> bool:
        return bool(np.median(tracks[a][1][k][f.rows]) <= lost_px)

    parts = around(anchors)
    held = [a for _, a in parts if holds(a)]
    if not held and blind:
        seeing = around([a for a in anchors if a not in blind])
        held = [a for _, a in seeing if holds(a)]
        if held and len(held) == len(seeing):
            parts = seeing  # both hold: blended as any two anchors are
    if held and held != [a for _, a in parts]:
        parts = [(1.0, held[0])]
    pose = np.zeros((n, 2))
    err = np.zeros(f.rows.stop - f.rows.start)
    for weight, a in parts:
        positions, errors = tracks[a]
        pose += weight * positions[k][f.rows][:n]
        err += weight * errors[k][f.rows]
    return pose, (err if parts else None)


def simplify_keys(series: np.ndarray, tolerance_px: float, keep: Sequence[int] = ()) -> list[int]:
    """The frames to keep so that linear interpolation between them stays within
    ``tolerance_px`` of every frame (Douglas–Peucker in time).

    Parameters
    ----------
    series : ndarray, shape (F, N, 2)
        A feature's control points at every frame.
    tolerance_px : float
        The largest distance, in pixels, of any control point at any frame from the
        interpolation of the kept frames.
    keep : frames always kept (the first and last always are).

    Examples
    --------
    >>> import numpy as np
    >>> line = np.array([[[t, 0.0]] for t in range(10)])  # uniform motion
    >>> simplify_keys(line, 0.1)
    [0, 9]
    >>> bend = np.array([[[t, 0.0 if t < 5 else t - 5.0]] for t in range(10)])
    >>> simplify_keys(bend, 0.1)
    [0, 5, 9]
    """
    count = len(series)
    kept = sorted({0, count - 1, *(k for k in keep if 0 <= k < count)})
    out: set[int] = set(kept)
    stack = list(zip(kept[:-1], kept[1:]))
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        w = ((np.arange(a + 1, b) - a) / (b - a))[:, None, None]
        line = series[a] * (1 - w) + series[b] * w
        dist = np.linalg.norm(series[a + 1:b] - line, axis=2).max(axis=1)
        worst = int(np.argmax(dist))
        if dist[worst] > tolerance_px:
            m = a + 1 + worst
            out.add(m)
            stack += [(a, m), (m, b)]
    return sorted(out)


def track(video: str | os.PathLike[str], scene: Any, frame: int = 0, **options: Any) -> Any:
    """Track the scene's drawing through the video; see :func:`track_dict` for the options.

    Returns
    -------
    inkwarp.Scene
        The scene with a key at every video frame for every feature but its cuts, which
        move nothing. Its image paths start from the input scene's folder, as that
        scene's did, so :meth:`inkwarp.Scene.save` writes them relative to where it saves.
    """
    from inkwarp import Scene
    from inkwarp.transfer import _folder

    base = options.pop("relative_to", None) or _folder(scene)
    return Scene.from_dict(track_dict(video, scene, frame, relative_to=base, **options), base_dir=base)


def rotoscope_example(examples_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                      quiet: bool = True) -> tuple[Path, Path]:
    """``make demo``'s actor-to-cat pipeline: ``rotoscope/actor.mp4`` tracked from the
    drawing ``rotoscope/actor.json`` (``actor-tracked.json`` in ``out_dir``), then
    transferred onto ``transfer/cat-target.json`` (``rotoscope.json``). Returns both paths.
    """
    from inkwarp.transfer import transfer_dict

    root, out = Path(examples_dir), Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    def bar(total: int) -> Callable[[], None] | None:
        if quiet:
            return None
        from inkwarp.cli._common import progress_bar

        bars.append(progress_bar(total, "rotoscope (track)"))
        return lambda: bars[-1].update(1)

    bars: list[Any] = []
    try:
        tracked = track_dict(root / "rotoscope" / "actor.mp4", root / "rotoscope" / "actor.json",
                             progress=bar, relative_to=out.resolve())
    finally:
        for b in bars:
            b.close()
    tracked_path = save_json(tracked, out / "actor-tracked.json")
    cat = transfer_dict(tracked_path, root / "transfer" / "cat-target.json",
                        relative_to=out.resolve())
    return tracked_path, save_json(cat, out / "rotoscope.json")


def check_output(path: str | os.PathLike[str], *, source: str | os.PathLike[str] | None = None,
                 option: str = "--scene") -> Path:
    """Check before any work that the file ``path`` can be written, as ``inkwarp render``
    and ``inkwarp new`` check theirs. Raises ``ValueError`` with the fix when ``path`` is
    a directory, when its folder does not exist (a mistyped folder is not made) or is a
    file, when the folder cannot be written, or when ``path`` is the input file
    ``source`` (given as ``option``), which writing would replace."""
    out = Path(path)
    if out.is_dir():
        raise InputError(f"{out}: is a directory; name a file, such as {out / ('out' + out.suffix)}")
    folder = out.absolute().parent
    above = folder
    while not above.exists() and above != above.parent:
        above = above.parent
    if above.is_dir() and not folder.exists():
        raise InputError(f"{out}: the directory {folder} does not exist; create it first")
    folder = above
    if not folder.is_dir():
        raise InputError(f"{out}: {folder} is a file, not a directory; choose another output path")
    from inkwarp.video import check_writable

    check_writable(out, folder)
    if source is not None:
        from inkwarp.outputs import check_not_the_input

        check_not_the_input(out, source, option, "-tracked")
    return out


def save_json(doc: dict[str, Any], path: str | os.PathLike[str]) -> Path:
    """Write a scene document: under a temporary name beside ``path``, then renamed."""
    from inkwarp._atomic import write_text

    out = Path(path)
    return write_text(out, json.dumps(doc, indent=1) + "\n", suffix=".json")

