"""Videos with known motion, for the tracker's tests and benchmark.

A picture (blurred noise at several scales: texture at every size an actor's skin or a
cat's fur has, with an optional flat patch that has almost none) is moved by a known map
``forward(points, k)`` and rendered frame by frame (``cv2.remap`` through the inverse
map), then encoded as H.264 (CRF 12), as footage would be. The truth at frame ``k`` of a
point traced on frame 0 is ``forward(point, k)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

Map = Callable[[np.ndarray, int], np.ndarray]


@dataclass
class Motion:
    name: str
    forward: Map          # rest points (N, 2) at frame 0 -> points at frame k
    inverse: Map          # points at frame k -> where they were at frame 0


def picture(width: int, height: int, seed: int = 1, flat: tuple[int, int, int, int] | None = None
            ) -> np.ndarray:
    """An RGB ``uint8`` texture; ``flat`` = (x0, y0, x1, y1) is a patch with a faint
    gradient instead (low texture)."""
    import cv2

    rng = np.random.default_rng(seed)
    out = np.zeros((height, width, 3), np.float32)
    for sigma, weight in ((1.2, 0.5), (3.0, 0.8), (8.0, 1.0), (24.0, 1.2)):
        noise = rng.standard_normal((height, width, 3)).astype(np.float32)
        blurred = cv2.GaussianBlur(noise, (0, 0), sigma)
        out += weight * blurred / (blurred.std() + 1e-9)
    out = (out - out.min()) / (out.max() - out.min()) * 220 + 18
    if flat is not None:
        x0, y0, x1, y1 = flat
        yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float32)
        ramp = 120 + 25 * (xx - x0) / max(x1 - x0, 1) + 10 * (yy - y0) / max(y1 - y0, 1)
        patch = np.repeat(ramp[..., None], 3, axis=2) * np.array([1.0, 0.9, 0.8], np.float32)
        # Feather the patch's edge over 6 px so it has no hard rim to track.
        mask = np.zeros((height, width), np.float32)
        mask[y0:y1, x0:x1] = 1
        mask = cv2.GaussianBlur(mask, (0, 0), 3.0)[..., None]
        full = out.copy()
        full[y0:y1, x0:x1] = patch
        full = cv2.GaussianBlur(full, (0, 0), 4.0)
        out = out * (1 - mask) + full * mask
    return np.clip(out, 0, 255).astype(np.uint8)


def translate(vx: float = 0.9, vy: float = 0.55) -> Motion:
    v = np.array([vx, vy])
    return Motion("translate", lambda p, k: p + v * k, lambda p, k: p - v * k)


def rotate(width: int, height: int, deg_per_frame: float = 0.6) -> Motion:
    c = np.array([(width - 1) / 2, (height - 1) / 2])

    def turn(p: np.ndarray, angle: float) -> np.ndarray:
        s, co = math.sin(angle), math.cos(angle)
        d = p - c
        return c + np.stack([co * d[:, 0] - s * d[:, 1], s * d[:, 0] + co * d[:, 1]], axis=1)

    rad = math.radians(deg_per_frame)
    return Motion("rotate", lambda p, k: turn(p, rad * k), lambda p, k: turn(p, -rad * k))


def warp(width: int, height: int, frames: int, amplitude_px: float = 7.0,
         centre: tuple[float, float] = (0.45, 0.5), radius: float = 0.25) -> Motion:
    """A local bulge: a Gaussian bump of displacement (standard deviation ``radius`` of the
    picture's smaller side, centred at ``centre`` in fractions of the picture) that grows
    and shrinks over the clip, plus a slow drift."""
    c = np.array([width * centre[0], height * centre[1]])
    sigma = min(width, height) * radius
    direction = np.array([1.0, 0.6]) / np.hypot(1.0, 0.6)

    def disp(p: np.ndarray, k: int) -> np.ndarray:
        a = amplitude_px * math.sin(math.pi * k / max(frames - 1, 1))
        g = np.exp(-np.sum((p - c) ** 2, axis=1) / (2 * sigma**2))
        return (a * g)[:, None] * direction + np.array([0.3, -0.2]) * k

    def forward(p: np.ndarray, k: int) -> np.ndarray:
        return p + disp(p, k)

    def inverse(q: np.ndarray, k: int) -> np.ndarray:
        p = q.copy()
        for _ in range(30):
            p = q - disp(p, k)
        return p

    return Motion("warp", forward, inverse)


def render(image: np.ndarray, motion: Motion, frames: int, noise: float = 0.0,
           seed: int = 0) -> list[np.ndarray]:
    """The picture moved by ``motion``, one RGB frame per k, with Gaussian sensor noise of
    standard deviation ``noise`` (grey levels), new in every frame."""
    import cv2

    h, w = image.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    grid = np.stack([xx.ravel(), yy.ravel()], axis=1)
    out = []
    for k in range(frames):
        src = motion.inverse(grid, k).astype(np.float32)
        frame = cv2.remap(image, src[:, 0].reshape(h, w), src[:, 1].reshape(h, w),
                          cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT101)
        if noise:
            grain = np.random.default_rng(seed + k).normal(0, noise, frame.shape)
            frame = np.clip(frame + grain, 0, 255).astype(np.uint8)
        out.append(frame)
    return out


def write_mp4(path: str | Path, frames: list[np.ndarray], fps: float = 24.0, crf: int = 12) -> Path:
    import imageio_ffmpeg

    h, w = frames[0].shape[:2]
    writer = imageio_ffmpeg.write_frames(
        str(path), (w, h), fps=fps, codec="libx264", quality=None, macro_block_size=1,
        output_params=["-crf", str(crf), "-preset", "veryfast"], ffmpeg_log_level="error")
    writer.send(None)
    for frame in frames:
        writer.send(np.ascontiguousarray(frame))
    writer.close()
    return Path(path)


def scene(width: int, height: int, features: list[dict]) -> dict:
    """A scene of the video's size holding ``features`` (traced on frame 0)."""
    return {"inkwarp": 1, "width": width, "height": height, "fps": 24, "duration": 1.0,
            "layers": [{"name": "footage"}], "features": features}


def drawing(width: int, height: int, seed: int = 3, region: tuple[int, int, int, int] | None = None
            ) -> list[dict]:
    """A drawing of splines, polylines and points spread over the picture (or over
    ``region``), away from the edges."""
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = region or (int(width * 0.15), int(height * 0.15), int(width * 0.85),
                                int(height * 0.85))
    feats: list[dict] = []
    for i in range(4):
        cx, cy = rng.uniform(x0 + 15, x1 - 15), rng.uniform(y0 + 15, y1 - 15)
        angle = rng.uniform(0, math.pi)
        length = min(x1 - x0, y1 - y0) * 0.35
        pts = []
        for t in np.linspace(-0.5, 0.5, 4):
            bend = 0.15 * length * math.sin(math.pi * (t + 0.5))
            pts.append([cx + t * length * math.cos(angle) - bend * math.sin(angle),
                        cy + t * length * math.sin(angle) + bend * math.cos(angle)])
        kind = "spline" if i % 2 == 0 else "polyline"
        feats.append({"id": f"{kind}{i}", "kind": kind, "rest": np.round(pts, 2).tolist()})
    for i in range(3):
        feats.append({"id": f"point{i}", "kind": "point",
                      "rest": [[round(float(rng.uniform(x0 + 5, x1 - 5)), 2),
                                round(float(rng.uniform(y0 + 5, y1 - 5)), 2)]]})
    return feats


def truth(features: list[dict], motion: Motion, frames: int) -> np.ndarray:
    """(frames, N, 2): every control point of ``features`` at every frame."""
    rest = np.concatenate([np.asarray(f["rest"], float) for f in features])
    return np.stack([motion.forward(rest, k) for k in range(frames)])


def tracked(doc: dict, frames: int) -> np.ndarray:
    """(frames, N, 2) from a tracked scene with a key at every frame."""
    out = np.zeros((frames, sum(len(f["rest"]) for f in doc["features"]), 2))
    col = 0
    for f in doc["features"]:
        n = len(f["rest"])
        for k, key in enumerate(f["keys"]):
            out[k, col:col + n] = key["points"]
        col += n
    return out
