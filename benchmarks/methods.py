"""Time each method to produce a 513 × 513 displacement field from N samples.

The paper's claim: the grid thin plate's cost does not grow with the drawing, while the
continuous interpolants pay for every sample at every pixel. Run with ``make bench`` or
``python benchmarks/methods.py [--size 513] [--n 100 1000] [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import inkwarp


def samples(n: int, size: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    points = rng.uniform(0, size - 1, (n, 2))
    displacements = rng.normal(0, 5, (n, 2))
    return points, displacements


def time_method(method: str, n: int, size: int, repeat: int) -> tuple[float, float]:
    points, displacements = samples(n, size, seed=n)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        inkwarp.interpolate(points, displacements, (size, size), method=method, max_samples=max(n, 1))
        times.append(time.perf_counter() - start)
    return statistics.median(times), min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=513)
    parser.add_argument("--n", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--methods", nargs="+", default=list(inkwarp.METHODS))
    args = parser.parse_args()

    methods = [m for m in args.methods if m != "tps" or hasattr(inkwarp, "thin_plate")]
    print(f"{args.size}×{args.size} displacement field from N random samples; median of "
          f"{args.repeat} runs on {os.cpu_count()} CPU(s).\n")
    print("| method | " + " | ".join(f"N={n}" for n in args.n) + f" | N={args.n[-1]} / N={args.n[0]} |")
    print("|---|" + "---:|" * (len(args.n) + 1))
    for method in methods:
        medians = [time_method(method, n, args.size, args.repeat)[0] for n in args.n]
        cells = " | ".join(f"{m * 1000:.1f} ms" for m in medians)
        print(f"| {method} | {cells} | {medians[-1] / medians[0]:.1f}× |", flush=True)

if __name__ == "__main__":
    main()
