"""Big frames: per-frame time split into solve, render and encode at 512×512, 1920×1080 and
3840×2160, rendered in one process and on a 2-worker local Ray cluster, with peak memory.

Each size runs in a child process of its own (so its peak memory is its own), the sizes
alternating round by round (the machine's speed drifts; ratios are taken within a round
and their median reported). Per frame:

- frame: the fastest warm-started frame (``Scene.frames``: solve + render; the fastest,
  because other work on the machine only ever adds time); cold: the first frame, solved
  from zero (one frame in 16 is);
- render: ``inkwarp.warp_image`` of the layer with one of the animation's fields (the
  fastest of 5);
- solve: frame − render (the warm solve, constraints and compositing);
- encode: the PNG (Pillow, inkwarp's level, ``imaging.PNG_COMPRESS_LEVEL``) and the H.264 MP4 (bundled ffmpeg) of the frames.

Ray: ``inkwarp.render(scene, DIR, ray=True)`` on ``ray.init(num_cpus=2)`` against
``inkwarp.render(scene, DIR)`` in the same child, startup not counted; chunks are cut at
the engine's 16-frame warm-start chains, so a 2-worker render needs more than 16 frames
(timed at 512² with 32 frames; ``--ray-all`` times every size with 32 frames).

Usage: python benchmarks/pipeline.py [--quick] [--rounds N] [--no-ray]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIZES = {"512²": (512, 512), "1920×1080": (1920, 1080), "3840×2160": (3840, 2160)}
FRAMES = {"512²": 32, "1920×1080": 8, "3840×2160": 3}
QUICK = {"512²": (128, 128, 8), "1920×1080": (480, 270, 8), "3840×2160": (960, 540, 4)}
#: Where the Ray render is timed: Ray chunks follow the 16-frame warm-start chains, so a
#: 2-worker render needs at least 17 frames; at the big sizes that is minutes of frames.
RAY_SIZES = ("512²",)


def child(width: int, height: int, frames: int, use_ray: bool) -> dict:
    import numpy as np
    from PIL import Image

    sys.path.insert(0, str(HERE))
    import inkwarp
    from scene import make_scene
    from inkwarp.video import write_frames

    scene, image = make_scene(width, height, frames)
    out: dict = {"width": width, "height": height, "frames": frames}
    times, rendered = [], []
    t0 = time.perf_counter()
    for frame in scene.frames():
        t1 = time.perf_counter()
        times.append(t1 - t0)
        rendered.append(frame)
        t0 = t1
    # The first frame of each 16-frame chain is solved from zero; the others warm-start.
    warm = [t for i, t in enumerate(times) if i % 16]
    out["cold_ms"] = 1e3 * times[0]
    out["frame_ms"] = 1e3 * min(warm or times)
    out["mean_ms"] = 1e3 * sum(times) / frames
    field = scene.field(frame=frames // 2)
    render = []
    for _ in range(5):
        t0 = time.perf_counter()
        inkwarp.warp_image(image, field)
        render.append(time.perf_counter() - t0)
    out["render_ms"] = 1e3 * min(render)
    out["solve_ms"] = out["frame_ms"] - out["render_ms"]
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        for i, frame in enumerate(rendered):
            Image.fromarray(frame).save(os.path.join(tmp, f"{i}.png"), compress_level=inkwarp.imaging.PNG_COMPRESS_LEVEL)
        out["png_ms"] = 1e3 * (time.perf_counter() - t0) / frames
        t0 = time.perf_counter()
        write_frames(os.path.join(tmp, "a.mp4"), rendered, fps=scene.fps)
        out["mp4_ms"] = 1e3 * (time.perf_counter() - t0) / frames
    del rendered
    out["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    if use_ray:
        import ray

        t0 = time.perf_counter()
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        out["ray_start_s"] = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            inkwarp.render(scene, os.path.join(tmp, "frames"), ray=True)
            out["ray_frame_ms"] = 1e3 * (time.perf_counter() - t0) / frames
            t0 = time.perf_counter()
            inkwarp.render(scene, os.path.join(tmp, "local"))
            out["local_png_frame_ms"] = 1e3 * (time.perf_counter() - t0) / frames
        ray.shutdown()
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small frames, for the smoke test")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--ray-all", action="store_true", help="time Ray at every size (32 frames)")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        w, h, n, r = (int(v) for v in args.child)
        print(json.dumps(child(w, h, n, bool(r))))
        return 0
    try:
        import ray  # noqa: F401
        use_ray = not args.no_ray
    except ImportError:
        use_ray = False
    results: dict[str, list[dict]] = {name: [] for name in SIZES}
    for _ in range(args.rounds):
        for name, (w, h) in SIZES.items():
            if args.quick:
                w, h, n = QUICK[name]
            else:
                n = 32 if args.ray_all and use_ray else FRAMES[name]
            ray_here = use_ray and (args.quick or args.ray_all or name in RAY_SIZES)
            done = subprocess.run([sys.executable, __file__, "--child", str(w), str(h), str(n),
                                   str(int(ray_here))], capture_output=True, text=True)
            if done.returncode != 0:
                print(done.stderr, file=sys.stderr)
                return 1
            results[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
            print(f"<!-- {name}: {done.stdout.strip().splitlines()[-1]} -->", flush=True)
    print(f"## Big frames: per-frame ms (median of {args.rounds} rounds), {os.cpu_count()} cores"
          + (" (--quick: small sizes)" if args.quick else "") + "\n")
    cols = ["cold", "frame", "solve", "render", "png", "mp4"] + (["ray 2 workers", "local"] if use_ray else [])
    print("| size | frames | " + " | ".join(cols) + " | peak MiB |")
    print("|---|---|" + "---|" * len(cols) + "---|")
    keys = ["cold_ms", "frame_ms", "solve_ms", "render_ms", "png_ms", "mp4_ms"] + (
        ["ray_frame_ms", "local_png_frame_ms"] if use_ray else [])
    for name, runs in results.items():
        w, h = runs[0]["width"], runs[0]["height"]
        cells = [f"{statistics.median(r[k] for r in runs):.0f}" if k in runs[0] else "–"
                 for k in keys]
        peak = max(r["peak_mib"] for r in runs)
        print(f"| {w}×{h} | {runs[0]['frames']} | " + " | ".join(cells) + f" | {peak:.0f} |")
    small, large = results["512²"], results["1920×1080"]
    pixels = (large[0]["width"] * large[0]["height"]) / (small[0]["width"] * small[0]["height"])
    print()
    for key in ("cold_ms", "frame_ms", "solve_ms", "render_ms", "png_ms"):
        ratio = statistics.median(b[key] / a[key] for a, b in zip(small, large))
        print(f"- {key[:-3]}: {large[0]['width']}×{large[0]['height']} / "
              f"{small[0]['width']}×{small[0]['height']} = {ratio:.1f}× (pixels {pixels:.1f}×)")
    if use_ray:
        for name, runs in results.items():
            if "ray_frame_ms" not in runs[0]:
                continue
            speed = statistics.median(r["local_png_frame_ms"] / r["ray_frame_ms"] for r in runs)
            print(f"- Ray speed-up at {runs[0]['width']}×{runs[0]['height']} "
                  f"({runs[0]['frames']} frames, one machine): {speed:.2f}× "
                  f"(Ray started in {statistics.median(r['ray_start_s'] for r in runs):.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
