"""Animation benchmark: per-frame time (solve + render) of a 100-frame 512×512 scene, cold
against warm-started, the renderer alone, and a 1920×1080 48-frame render's peak memory.

The peer is what a user would write with scikit-image instead: fit a thin-plate spline to
the same samples every frame and `skimage.transform.warp` the image (backward mapping).
Times are medians; ratios are peer / inkwarp.

Usage: python benchmarks/scene.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from PIL import Image

import inkwarp


def art(width: int, height: int) -> np.ndarray:
    """A textured test picture: checks, rings and a colour ramp."""
    ys, xs = np.mgrid[0:height, 0:width]
    checks = ((xs // 32 + ys // 32) % 2).astype(np.float64)
    rings = 0.5 + 0.5 * np.sin(np.hypot(xs - width / 2, ys - height / 2) / 6)
    rgba = np.zeros((height, width, 4), np.uint8)
    rgba[..., 0] = 255 * (0.3 + 0.7 * checks * xs / width)
    rgba[..., 1] = 255 * rings
    rgba[..., 2] = 255 * (ys / height)
    rgba[..., 3] = 255
    return rgba


def scene_dict(width: int, height: int, frames: int, fps: float, image_uri: str) -> dict:
    """A dozen features (splines, polylines, points) swaying over the animation."""
    rng = np.random.default_rng(1)
    duration = frames / fps
    features = []
    for i in range(12):
        kind = ["spline", "polyline", "point"][i % 3]
        n = 1 if kind == "point" else 4
        cx, cy = rng.uniform(0.15, 0.85) * width, rng.uniform(0.15, 0.85) * height
        rest = [[cx + 30 * j, cy + 10 * np.sin(j)] for j in range(n)]
        keys = []
        for k, t in enumerate(np.linspace(0.0, duration, 5)):
            dx, dy = 12 * np.sin(k + i), 10 * np.cos(1.3 * k + i)
            keys.append({"t": float(t), "points": [[x + dx, y + dy] for x, y in rest]})
        features.append({"id": f"f{i}", "kind": kind, "rest": rest, "keys": keys})
    return {
        "inkwarp": 1, "width": width, "height": height, "fps": fps, "duration": duration,
        "layers": [{"name": "picture", "image": image_uri}],
        "features": features,
    }


def make_scene(width: int, height: int, frames: int, fps: float = 24.0) -> tuple[inkwarp.Scene, np.ndarray]:
    image = art(width, height)
    return inkwarp.Scene.from_dict(
        scene_dict(width, height, frames, fps, inkwarp.image_data_uri(image))), image


def per_frame(fn, count: int) -> float:
    times = []
    for i in range(count):
        t0 = time.perf_counter()
        fn(i)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def skimage_frame(scene: inkwarp.Scene, image: np.ndarray, frame: int) -> np.ndarray:
    """The peer: a thin-plate spline fitted to the same samples, backward-mapped warp."""
    from skimage.transform import ThinPlateSplineTransform, warp

    pts, disp = scene_samples(scene, frame)
    # warp() wants the map from output to input: fit posed -> rest.
    tform = ThinPlateSplineTransform.from_estimate(pts + disp, pts)
    return warp(image, tform, order=1, preserve_range=True).astype(np.uint8)


def scene_samples(scene: inkwarp.Scene, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """Every feature's control points at rest and at this frame (the peer's constraints)."""
    t = frame / scene.fps
    doc = scene.to_dict()
    rest, posed = [], []
    for feature in doc["features"]:
        keys = feature.get("keys", [])
        # Linear in time between the two keys around t: close enough to drive the peer.
        times = [k["t"] for k in keys]
        j = int(np.clip(np.searchsorted(times, t) - 1, 0, len(keys) - 2))
        a = (t - times[j]) / (times[j + 1] - times[j])
        pose = (1 - a) * np.asarray(keys[j]["points"]) + a * np.asarray(keys[j + 1]["points"])
        rest += feature["rest"]
        posed += pose.tolist()
    rest, posed = np.asarray(rest, float), np.asarray(posed, float)
    return rest, posed - rest


def big_child(frames: int) -> None:
    import resource

    scene, _ = make_scene(1920, 1080, frames)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        for i, frame in enumerate(scene.frames()):
            Image.fromarray(frame).save(os.path.join(tmp, f"{i:04d}.png"), compress_level=1)
        seconds = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"seconds": seconds, "peak_mib": peak, "frames": frames}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        big_child(args.child)
        return

    size, frames = (128, 12) if args.quick else (512, 100)
    scene, image = make_scene(size, size, frames)
    print(f"## {frames}-frame {size}×{size} scene, {len(scene.features)} features, "
          f"{os.cpu_count()} cores\n")

    cold = per_frame(lambda i: scene.render(frame=i), min(frames, 20))

    def sequential_warm() -> list[float]:
        times, t0 = [], time.perf_counter()
        for _ in scene.frames(threads=1):
            t1 = time.perf_counter()
            times.append(t1 - t0)
            t0 = t1
        return times

    warm_times = sequential_warm()
    warm = statistics.median(warm_times[1:])
    t0 = time.perf_counter()
    count = sum(1 for _ in scene.frames())
    parallel = (time.perf_counter() - t0) / count

    field = scene.field(frame=frames // 2)
    render_alone = statistics.median(
        [timed(lambda: inkwarp.warp_image(image, field)) for _ in range(15)])
    peer_frames = 3 if args.quick else 5
    peer = per_frame(lambda i: skimage_frame(scene, image, i * 7), peer_frames)

    print("| per frame (solve + render) | ms | vs cold |")
    print("|---|---|---|")
    print(f"| cold (each frame solved from zero) | {cold * 1e3:.1f} | 1.00 |")
    print(f"| warm (started from the earlier frames, 1 thread) | {warm * 1e3:.1f} | {warm / cold:.2f} |")
    print(f"| warm, frames in parallel (all cores), wall / frame | {parallel * 1e3:.1f} | {parallel / cold:.2f} |")
    print(f"| render alone ({size}×{size} layer) | {render_alone * 1e3:.1f} | |")
    print(f"| scikit-image TPS fit + warp (peer) | {peer * 1e3:.1f} | {peer / warm:.0f}× inkwarp warm |")
    if not args.quick:
        out = subprocess.run([sys.executable, __file__, "--child", "48"], check=True,
                             capture_output=True, text=True)
        res = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"\n1920×1080, 48 frames to PNG: {res['seconds']:.1f} s "
              f"({res['seconds'] / 48 * 1e3:.0f} ms/frame), peak memory {res['peak_mib']:.0f} MiB")


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
