"""Cycles of the thin-plate solve on thin strands as the picture grows (issue 42 item 1).

The oracle families (`tests/test_solver_families.py`) check combs and antialiased
character mattes at 40×64 and 72×64. Real mattes have the same shapes at photograph size:
strands stay 1–2 px wide while they grow longer. This benchmark scales both families and
reports the cycles, convergence and time of a cold solve at default settings (but
`max_cycles`, raised so the count is seen), one row per size:

- a comb: the mask of `test_comb_with_one_pixel_gaps` (a back bar and teeth 1 or 2 px
  wide with 1 px gaps), points on the bar and on every 4·scale-th tip;
- a character: `test_antialiased_character_mattes`'s problem (seed 0): body, head on a thin
  neck, an arm, and hair strands 0.3–1.6 px wide whose length and number grow with the
  scale.

The thin parts solved whole (`solve/strands.rs`) keep these counts nearly flat; before
them the combs took 62/502/841 and 96/403/2000+ cycles (see docs/dev/ablation.md,
"Strands as the picture grows" and "Ninth change").

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
from test_solver_families import character_problem, comb_mask  # noqa: E402


def comb(tooth: int, scale: int):
    """The comb family's mask at `scale`, points on the bar and on every 4·scale-th tip (the
    test takes the first four tips of every fourth)."""
    m = comb_mask(tooth, scale)
    h, w = m.shape
    tips = list(range(2, w - 2, tooth + 1))[:: 4 * scale]
    pts = np.array([[5.0, 4.0], [w / 2, 5.0], [w - 6.0, 3.0]] + [[float(x), h - 4.0] for x in tips])
    disp = np.random.default_rng(tooth).normal(0, 4, (len(pts), 2))
    return m, pts, disp


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="scale 1 (and 2 for the character): a smoke run")
    ap.add_argument("--max-cycles", type=int, default=2000)
    args = ap.parse_args()
    scales = (1, 2) if args.quick else (1, 2, 4, 8)
    print("| family | grid | cycles | converged | seconds |")
    print("|---|---|---|---|---|")
    cases = [(f"comb, {t} px teeth", lambda s, t=t: comb(t, s)) for t in (1, 2)]
    cases.append(("character with hair", lambda s: character_problem(0, s)))
    for name, make in cases:
        for s in scales:
            if name.startswith("comb") and args.quick and s > 1:
                continue
            m, pts, disp = make(s)
            t = time.perf_counter()
            _, rep = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m, max_cycles=args.max_cycles)
            print(f"| {name} | {m.shape[0]}×{m.shape[1]} | {rep.cycles} | {rep.converged} | "
                  f"{time.perf_counter() - t:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
