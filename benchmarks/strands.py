"""Cycles of the thin-plate solve on thin strands as the picture grows (issue 42 item 1).

The oracle families (`tests/test_solver_families.py`) check combs and antialiased
character mattes at 40×64 and 72×64. Real mattes have the same shapes at photograph size:
strands stay 1–2 px wide while they grow longer. This benchmark scales both families and
reports the cycles, convergence and time of a cold solve at default settings (but
`max_cycles`, raised so the count is seen), one row per size:

- a comb: a back bar and teeth 1 or 2 px wide with 1 px gaps, points on the bar and on
  some tips (`test_comb_with_one_pixel_gaps` at scale 1);
- a character: body, head on a thin neck, an arm, and hair strands 0.3–1.6 px wide whose
  length (and number) grows with the scale (`test_antialiased_character_mattes` at 1).

A coarse space that carries the strands' own motions keeps these counts flat; the present
one does not (see docs/dev/ablation.md, "Strands as the picture grows").

Usage: python benchmarks/strands.py [--quick] [--max-cycles 2000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import inkwarp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_solver_families import antialiased_stroke, random_points  # noqa: E402


def comb(tooth: int, scale: int):
    """The comb family at `scale` (1: the test's 40×64), teeth `tooth` px wide."""
    h, w, bar = 40 * scale, 64 * scale, 6 * scale
    m = np.zeros((h, w), np.uint8)
    m[2 : 2 + bar, 2 : w - 2] = 1
    for x in range(2, w - 2, tooth + 1):
        m[2 + bar : h - 2, x : x + tooth] = 1
    tips = list(range(2, w - 2, tooth + 1))[:: 4 * scale]
    pts = np.array([[5.0, 4.0], [w / 2, 5.0], [w - 6.0, 3.0]] + [[float(x), h - 4.0] for x in tips])
    disp = np.random.default_rng(tooth).normal(0, 4, (len(pts), 2))
    return m, pts, disp


def character(seed: int, s: int):
    """The antialiased character family at scale `s`: strands keep their width."""
    rng = np.random.default_rng(seed)
    shape = (72 * s, 64 * s)
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    body = np.clip((1 - np.hypot((xs - 32 * s) / (14 * s), (ys - 48 * s) / (18 * s))) * 14 * s + 0.5, 0, 1)
    head = np.clip(11 * s + 0.5 - np.hypot(xs - 32 * s, ys - 16 * s), 0, 1)
    alpha = np.maximum(body, head)
    neck = antialiased_stroke(shape, (32 * s, 26 * s), (32 * s, 31 * s), (1.2 + 0.4 * rng.random()) * s)
    alpha = np.maximum(alpha, neck)
    for _ in range(int(rng.integers(4, 8)) * s):
        a = np.pi * (1.1 + 0.8 * rng.random())
        p = (32 * s + 10.5 * s * np.cos(a), 16 * s + 10.5 * s * np.sin(a))
        length = rng.uniform(6, 14) * s
        q = (p[0] + length * np.cos(a), p[1] + length * np.sin(a))
        alpha = np.maximum(alpha, antialiased_stroke(shape, p, q, rng.uniform(0.3, 1.6)))
    arm = antialiased_stroke(shape, (20 * s, 44 * s), (4 * s, (30 + 8 * rng.random()) * s), 1.5 * s)
    m = (np.maximum(alpha, arm) > 0).astype(np.uint8)
    rng = np.random.default_rng(seed)
    body_box = np.zeros_like(m)
    body_box[36 * s : 64 * s, 22 * s : 42 * s] = 1
    head_box = np.zeros_like(m)
    head_box[10 * s : 22 * s, 27 * s : 37 * s] = 1
    pts = np.vstack([random_points(rng, m & body_box, 4), random_points(rng, m & head_box, 2)])
    return m, pts, rng.normal(0, 5, (6, 2))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="scale 1 (and 2 for the character): a smoke run")
    ap.add_argument("--max-cycles", type=int, default=2000)
    args = ap.parse_args()
    scales = (1, 2) if args.quick else (1, 2, 4, 8)
    print("| family | grid | cycles | converged | seconds |")
    print("|---|---|---|---|---|")
    cases = [(f"comb, {t} px teeth", lambda s, t=t: comb(t, s)) for t in (1, 2)]
    cases.append(("character with hair", lambda s: character(0, s)))
    for name, make in cases:
        for s in scales:
            if name.startswith("comb") and (s > 4 or (args.quick and s > 1)):
                continue  # a comb of 320×512 runs past any useful budget
            m, pts, disp = make(s)
            t = time.perf_counter()
            _, rep = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m, max_cycles=args.max_cycles)
            print(f"| {name} | {m.shape[0]}×{m.shape[1]} | {rep.cycles} | {rep.converged} | "
                  f"{time.perf_counter() - t:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
