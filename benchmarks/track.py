"""`inkwarp track` against the trackers users would otherwise reach for, on videos with
known motion.

Each video is a picture (textured, with a flat low-texture patch) moved by a known map
(benchmarks/synthetic_video.py) and encoded as H.264; a drawing is traced on frame 0, with
features on texture and features inside the flat patch. Three trackers follow the same
control points through it, in the same run, taking turns round by round:

- **inkwarp**: `inkwarp.track_dict` (DIS flow, Lucas-Kanade refinement with
  forward-backward checks, registration to the anchor frame, thin-plate regularisation);
- **LK**: plain frame-to-frame pyramidal Lucas-Kanade (21 px window, 3 levels) on the
  control points;
- **DIS**: plain frame-to-frame DIS dense flow (preset medium), each point moved by the flow
  interpolated where it is.

Accuracy: the distance of every control point at every frame from the truth (median, 90th
percentile, share within 1, 2 and 4 px), and the drift (median distance at the last frame).
Time: wall milliseconds per frame, median over the rounds (decoding included for all three).

    python benchmarks/track.py [--quick] [--rounds 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import synthetic_video as sv  # noqa: E402


#: Sensor noise of the footage (grey levels, standard deviation, new in every frame).
NOISE = 2.0


def plain_lk(video: Path, rest: np.ndarray) -> np.ndarray:
    import cv2

    from inkwarp.track import read_video

    clip = read_video(video)
    out = [rest.copy()]
    pts = rest.astype(np.float32).reshape(-1, 1, 2)
    for a, b in zip(clip.frames[:-1], clip.frames[1:]):
        nxt, _status, _ = cv2.calcOpticalFlowPyrLK(
            a, b, pts, None, winSize=(21, 21), maxLevel=3,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 0.005))
        pts = nxt
        out.append(pts.reshape(-1, 2).astype(np.float64))
    return np.stack(out)


def plain_dis(video: Path, rest: np.ndarray) -> np.ndarray:
    import cv2

    from inkwarp.track import _bilinear, read_video

    clip = read_video(video)
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    out = [rest.copy()]
    pts = rest.copy()
    for a, b in zip(clip.frames[:-1], clip.frames[1:]):
        pts = pts + _bilinear(dis.calc(a, b, None), pts)
        out.append(pts.copy())
    return np.stack(out)


def inkwarp_tracker(video: Path, features: list[dict], width: int, height: int) -> np.ndarray:
    import warnings

    import inkwarp
    from inkwarp.errors import InkwarpWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InkwarpWarning)
        doc = inkwarp.track_dict(video, sv.scene(width, height, features))
    return sv.tracked(doc, len(doc["features"][0]["keys"]))


def stats(errors: np.ndarray) -> dict[str, float]:
    flat = errors.ravel()
    return {"median": float(np.median(flat)), "p90": float(np.percentile(flat, 90)),
            "1px": float(np.mean(flat <= 1)), "2px": float(np.mean(flat <= 2)),
            "4px": float(np.mean(flat <= 4)), "drift": float(np.median(errors[-1]))}


def case(width: int, height: int, frames: int, motion_name: str, rounds: int, tmp: Path
         ) -> list[tuple[str, str, dict[str, float], float]]:
    flat = (int(width * 0.36), int(height * 0.33), int(width * 0.64), int(height * 0.67))
    image = sv.picture(width, height, seed=11, flat=flat)
    motion = (sv.warp(width, height, frames, amplitude_px=0.02 * min(width, height),
                      centre=(0.4, 0.45), radius=0.35)
              if motion_name == "warp" else sv.rotate(width, height, 0.5))
    video = sv.write_mp4(tmp / f"{motion_name}-{width}.mp4",
                         sv.render(image, motion, frames, noise=NOISE))
    inset = 14
    low_region = (flat[0] + inset, flat[1] + inset, flat[2] - inset, flat[3] - inset)
    textured = [f for f in sv.drawing(width, height, seed=4)
                if not _inside(np.asarray(f["rest"]), flat, -12)]
    low = [{**f, "id": "flat-" + f["id"]} for f in sv.drawing(width, height, seed=8, region=low_region)]
    features = textured + low
    rest = np.concatenate([np.asarray(f["rest"], float) for f in features])
    is_low = np.concatenate([np.full(len(f["rest"]), f in low) for f in features])
    truth = sv.truth(features, motion, frames)
    runners = {
        "inkwarp": lambda: inkwarp_tracker(video, features, width, height),
        "LK": lambda: plain_lk(video, rest),
        "DIS": lambda: plain_dis(video, rest),
    }
    times: dict[str, list[float]] = {name: [] for name in runners}
    results: dict[str, np.ndarray] = {}
    for r in range(rounds):
        order = list(runners) if r % 2 == 0 else list(reversed(runners))
        for name in order:
            start = time.perf_counter()
            results[name] = runners[name]()
            times[name].append((time.perf_counter() - start) / frames * 1000)
    rows = []
    for name in runners:
        errors = np.linalg.norm(results[name] - truth, axis=2)
        ms = statistics.median(times[name])
        rows.append((name, "textured", stats(errors[:, ~is_low]), ms))
        rows.append((name, "low-texture", stats(errors[:, is_low]), ms))
    return rows


def _inside(points: np.ndarray, rect: tuple[int, int, int, int], margin: int) -> bool:
    x0, y0, x1, y1 = rect
    return bool(((points[:, 0] >= x0 + margin) & (points[:, 0] <= x1 - margin)
                 & (points[:, 1] >= y0 + margin) & (points[:, 1] <= y1 - margin)).any())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one small video (a smoke run)")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    sizes = [(256, 192, 16)] if args.quick else [(512, 512, 48), (1920, 1080, 24)]
    motions = ["warp"] if args.quick else ["warp", "rotate"]
    print(f"Control-point error against the known motion (px) and wall ms per frame; "
          f"{args.rounds} rounds, trackers in alternating order, {os.cpu_count()} CPU(s).\n")
    print("| video | motion | features | tracker | median | p90 | ≤1 px | ≤2 px | ≤4 px "
          "| drift | ms/frame |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|")
    summary = []
    with tempfile.TemporaryDirectory() as tmp:
        for width, height, frames in sizes:
            for motion in motions:
                rows = case(width, height, frames, motion, args.rounds, Path(tmp))
                for name, kind, s, ms in rows:
                    print(f"| {width}×{height}×{frames} | {motion} | {kind} | {name} | "
                          f"{s['median']:.2f} | {s['p90']:.2f} | {s['1px']:.0%} | {s['2px']:.0%} "
                          f"| {s['4px']:.0%} | {s['drift']:.2f} | {ms:.0f} |", flush=True)
                ours = {k: s for n, k, s, _ in rows if n == "inkwarp"}
                for n, k, s, _ in rows:
                    if n != "inkwarp" and k == "low-texture":
                        summary.append(f"{width}×{height} {motion}, low-texture: {n} median "
                                       f"{s['median']:.2f} px = {s['median'] / max(ours[k]['median'], 1e-9):.1f}× "
                                       f"inkwarp's {ours[k]['median']:.2f} px")
    print()
    for line in summary:
        print(f"- {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
